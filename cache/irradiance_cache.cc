// Lock-free octree irradiance cache; see irradiance_cache.h for the layout and its invariants.
#include "cache/irradiance_cache.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <new>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "cache/irradiance_weight.h"
#include "cache/local_linear_fit.h"

namespace irfarm {
namespace {

constexpr double kGridRes = double(1u << 20);  // cells per axis at the deepest level

// The root cube extends the scene bounds by this fraction of their largest extent on every side,
// so that the validity boxes of records on the scene's outer walls (a_max * R_i, typically well
// under a quarter of the scene) still fit inside it. Records that do not fit go to the root
// node, which every lookup scans, so this only matters for speed, never for correctness.
constexpr double kRootPadding = 0.25;

// A record is stored at the deepest level whose cell edge is at least this many times its largest
// reach a_max * R_i. Larger cells mean fewer nodes a lookup visits but more candidates per node.
// Measured on bench_micro's caches (1k-100k records, lookups at a_max / 2), ns per lookup at 100k
// relative to 2: 0.5 -> 1.7x, 1 -> 1.5x, 1.5 -> 1.6x, 4 -> 1.0x, 8 -> 1.5x; 2 was the fastest
// at 1k and 10k too, and keeps the octree's own memory under the records' (see MemoryUse).
constexpr double kCellPerReach = 2.0;

// A leaf gets children once this many records that belong deeper have been stored in it. Bounds
// the nodes per record (at most 8 / kSplitAfter groups of 8 nodes) for sparse caches; measured on
// bench_micro's caches, lookups were as fast with 8 as with immediate splitting.
constexpr int kSplitAfter = 8;

// Relative slack on a record's reach a * R_i. RecordWeight only counts a record when the float
// |x - x_i| < a * R_i, which bounds the true distance by a * R_i * (1 + ~1e-6) (a few
// roundings); 1e-4 covers that with margin. The grown-cell test is done in double on the grid,
// whose mapping is monotone, so containment carries over exactly.
constexpr double kReachSlack = 1e-4;

// Deepest recursion of a lookup: kMaxDepth + 1 levels, each pushing at most 8 children, plus
// the roots of the other trees and classes waiting underneath.
constexpr int kLookupStack = 8 * (20 + 1) + 2 * 6;

// Bit k (k < 4) set when point k of the structure-of-arrays (xs, ys, zs, rs), from index 0, is
// within reach of p: |p - x_k|^2 < reach^2 with reach = alpha * r_k + beta > 0. With beta = 0 it is
// RecordWeight's distance test in the same float operations (SSE does not fuse multiply-adds;
// adding 0 is exact), so it never rejects a record the rule counts.
inline int WithinReach4(const float* xs, const float* ys, const float* zs, const float* rs,
                        const Vec3& p, float alpha, float beta) {
#if defined(__SSE2__)
  const __m128 dx = _mm_sub_ps(_mm_set1_ps(p.x), _mm_loadu_ps(xs));
  const __m128 dy = _mm_sub_ps(_mm_set1_ps(p.y), _mm_loadu_ps(ys));
  const __m128 dz = _mm_sub_ps(_mm_set1_ps(p.z), _mm_loadu_ps(zs));
  const __m128 reach =
      _mm_add_ps(_mm_mul_ps(_mm_set1_ps(alpha), _mm_loadu_ps(rs)), _mm_set1_ps(beta));
  const __m128 d2 =
      _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
  return _mm_movemask_ps(_mm_and_ps(_mm_cmpgt_ps(reach, _mm_setzero_ps()),
                                    _mm_cmplt_ps(d2, _mm_mul_ps(reach, reach))));
#else
  int mask = 0;
  for (int k = 0; k < 4; ++k) {
    const float dx = p.x - xs[k], dy = p.y - ys[k], dz = p.z - zs[k];
    const float reach = alpha * rs[k] + beta;
    mask |= int(reach > 0 && dx * dx + dy * dy + dz * dz < reach * reach) << k;
  }
  return mask;
#endif
}

// Bit i set when child i of a node (cell edge `half` grid units, low corner lo, midpoint mid;
// bit k of i: the upper half on axis k) should be entered by a walk from gx: radius[i] > 0 (the
// largest R in the child's subtree; 0 = empty) and, on each axis, lo_i - grow_i <= gx <=
// lo_i + half + grow_i with grow_i = radius[i] * reach_scale + margin. Four children per SSE step,
// in the scalar test's float operations (SSE does not fuse multiply-adds), so both enter the same.
inline unsigned EnterChildren(const float radius[8], const float gx[3], const float lo[3],
                              const float mid[3], float half, float reach_scale, float margin) {
#if defined(__SSE2__)
  unsigned enter = 0;
  for (int g = 0; g < 2; ++g) {  // children 4g .. 4g + 3
    const __m128 r = _mm_loadu_ps(radius + 4 * g);
    const __m128 grow = _mm_add_ps(_mm_mul_ps(r, _mm_set1_ps(reach_scale)), _mm_set1_ps(margin));
    __m128 ok = _mm_cmpgt_ps(r, _mm_setzero_ps());
    // The children's low corners: x alternates (bit 0), y in pairs (bit 1), z by group (bit 2).
    const __m128 lo_k[3] = {_mm_setr_ps(lo[0], mid[0], lo[0], mid[0]),
                            _mm_setr_ps(lo[1], lo[1], mid[1], mid[1]),
                            _mm_set1_ps(g == 0 ? lo[2] : mid[2])};
    const __m128 h = _mm_set1_ps(half);
    for (int k = 0; k < 3; ++k) {
      const __m128 x = _mm_set1_ps(gx[k]);
      ok = _mm_and_ps(ok, _mm_cmpge_ps(x, _mm_sub_ps(lo_k[k], grow)));
      ok = _mm_and_ps(ok, _mm_cmple_ps(x, _mm_add_ps(_mm_add_ps(lo_k[k], h), grow)));
    }
    enter |= unsigned(_mm_movemask_ps(ok)) << (4 * g);
  }
  return enter;
#else
  unsigned enter = 0;
  for (int i = 0; i < 8; ++i) {
    const float grow = radius[i] * reach_scale + margin;
    bool in = radius[i] > 0;
    for (int k = 0; k < 3; ++k) {
      const float l = ((i >> k) & 1) ? mid[k] : lo[k];
      in &= (gx[k] >= l - grow) & (gx[k] <= l + half + grow);
    }
    enter |= unsigned(in) << i;
  }
  return enter;
#endif
}

}  // namespace

template <typename F>
void IrradianceCache::ForEachWithin(const Block* head, const Vec3& p, float alpha, float beta,
                                    F&& f) {
  for (const Block* b = head; b != nullptr; b = b->next) {
    const uint64_t ready = b->ready.load(std::memory_order_acquire);
    if (ready == 0) continue;
    // Branch-free pass over the hot arrays, then f on the few hits: a mispredicted branch per
    // candidate would cost more than the test itself. Only ready slots are read: a group of 4 all
    // ready at once, the ready ones of a partial group one by one (a slot not yet ready may be
    // being written by another thread's insert: a data race ThreadSanitizer found).
    const int end = 64 - __builtin_clzll(ready);  // past the last ready slot
    uint64_t hits = 0;
    for (int i = 0; i < end; i += 4) {
      const uint64_t group = (ready >> i) & 0xF;
      int mask = 0;
      if (group == 0xF) {
        mask = WithinReach4(b->x() + i, b->y() + i, b->z() + i, b->radius() + i, p, alpha, beta);
      } else {
        for (uint64_t g = group; g != 0; g &= g - 1) {
          const int j = i + __builtin_ctzll(g);
          const float dx = p.x - b->x()[j], dy = p.y - b->y()[j], dz = p.z - b->z()[j];
          const float reach = alpha * b->radius()[j] + beta;
          mask |= int(reach > 0 && dx * dx + dy * dy + dz * dz < reach * reach) << (j - i);
        }
      }
      hits |= uint64_t(mask) << i;
    }
    for (; hits != 0; hits &= hits - 1) f(b, __builtin_ctzll(hits));
  }
}

// Running sums of one lookup; in double so that many records of very different weight (1/a up to
// kWardMaxWeight) sum without loss.
struct IrradianceCache::Accumulator {
  // A constructor, not aggregate initialization, which zero-filled `pending` on every lookup (a
  // 256-byte memset, 4% of a region lookup's time).
  Accumulator(const Vec3& x_in, const Vec3& n_in, float a_in, int max_level_in, float narrow_in,
              bool linear_fit_in)
      : x(x_in),
        n(n_in),
        a(a_in),
        max_level(max_level_in),
        narrow(narrow_in),
        linear_fit(linear_fit_in) {}
  Vec3 x, n;
  float a;
  int max_level;
  float narrow;  // LookupInfo::counts_at_narrow's accuracy (0: none)
  bool counts_at_narrow = false;
  double weight = 0, weight_sq = 0, narrow_weight = 0;
  double narrow_e[3] = {0, 0, 0};
  double e[3] = {0, 0, 0};
  int count = 0;
  int remote = 0;   // counted records with origin != 0
  bool linear_fit;  // CacheSettings::linear_fit
  LocalLinearFit fit;
  Vec3 fit_s, fit_t;  // the fit's tangent frame (made at the first record taken)
  static constexpr int kPending = 32;
  uint64_t pending[kPending];  // RecordRefs of records within reach not weighed yet
  int pending_count = 0;

  void Add(const IrradianceRecord& r) {
    if (r.level > max_level) return;
    const float w = RecordWeight(x, n, a, r);
    if (w > 0) {
      Take(w, r.irradiance, r.origin != 0, r.position);
      Narrow(w, r.position, r.normal, r.radius, r.irradiance);
    }
  }
  // For a record that counts at a (weight w): does it count at the narrow accuracy too? Of
  // RecordWeight's tests, only eps < narrow (w > 1 / narrow; the reach test follows from it) and
  // the in-front tolerance, which scales with the accuracy, can differ. A weight at its cap
  // (kWardMaxWeight: eps below 1e-3) says too little for a narrow accuracy under 1e-3: there eps
  // itself is tested (no lookup counted at a narrow accuracy under 1e-3 before).
  void Narrow(float w, const Vec3& position, const Vec3& normal, float radius,
              const Vec3& irradiance) {
    if (!(narrow > 0)) return;
    const bool within =
        w < kWardMaxWeight ? w > 1 / narrow : WardEpsilon(x, n, position, normal, radius) < narrow;
    if (within && !IsInFront(x, n, narrow, position, normal, radius)) {
      counts_at_narrow = true;
      narrow_weight += w;
      for (int k = 0; k < 3; ++k) narrow_e[k] += double(w) * irradiance[k];
    }
  }
  // A record that counts with weight w > 0.
  void Take(float w, const Vec3& irradiance, bool from_elsewhere, const Vec3& position) {
    weight += w;
    weight_sq += double(w) * w;
    for (int k = 0; k < 3; ++k) e[k] += double(w) * irradiance[k];
    ++count;
    remote += int(from_elsewhere);
    if (linear_fit) {
      if (count == 1) MakeFrame(n, &fit_s, &fit_t);
      const Vec3 d = position - x;
      fit.Add(w, Dot(d, fit_s), Dot(d, fit_t), irradiance);
    }
  }
  // Scans the ready slots of one node's blocks: squared-distance reject on the hot part, the full
  // rule (RecordWeight, the same as brute force) on the few records within reach.
  void Scan(const Block* head) {
    ForEachWithin(head, x, a, 0.0f, [this](const Block* b, int i) { Defer(b, i); });
  }
  // Records within reach are weighed after the walk (or when kPending are waiting), with their
  // cold parts prefetched now: the cache misses on them then overlap with the rest of the walk.
  void Defer(const Block* b, int i) {
    __builtin_prefetch(&b->cold()[i]);
    if (pending_count == kPending) Flush();
    pending[pending_count++] = RefOf(b, i);
  }
  void Flush() {
    for (int k = 0; k < pending_count; ++k) {
      const Block* b = BlockOf(pending[k]);
      const int i = SlotOf(pending[k]);
      // Level and facing first, from the cold part alone (RecordWeight's own first test).
      const Cold& c = b->cold()[i];
      if (c.level <= max_level && Dot(n, c.normal) > 0) Add(b->Record(i));
    }
    pending_count = 0;
  }
  bool Finish(Vec3* irradiance, LookupInfo* info) {
    Flush();
    if (info != nullptr) {
      info->records_used = count;
      info->weight_sum = float(weight);
      info->weight_sq_sum = float(weight_sq);
      info->remote_records_used = remote;
      info->counts_at_narrow = counts_at_narrow;
      if (counts_at_narrow)
        info->narrow_irradiance =
            Vec3(float(narrow_e[0] / narrow_weight), float(narrow_e[1] / narrow_weight),
                 float(narrow_e[2] / narrow_weight));
      info->from_region = false;
    }
    if (count == 0) return false;
    if (!linear_fit || !fit.ValueAtOrigin(irradiance))
      *irradiance = Vec3(float(e[0] / weight), float(e[1] / weight), float(e[2] / weight));
    return true;
  }
};

IrradianceRecord IrradianceCache::Block::Record(int i) const {
  const Cold& c = cold()[i];
  IrradianceRecord r;
  r.position = Vec3(x()[i], y()[i], z()[i]);
  r.normal = c.normal;
  r.irradiance = c.irradiance;
  r.radius = std::min(radius()[i], c.clamped.load(std::memory_order_relaxed));
  r.origin = c.origin;
  r.level = c.level;
  r.occluder = UnpackOccluder(c.occluder);
  return r;
}

IrradianceCache::IrradianceCache(const CacheSettings& settings)
    : max_accuracy_(ClampedMaxAccuracy(settings.max_accuracy)),
      neighbour_slope_(settings.neighbour_slope > 0 && std::isfinite(settings.neighbour_slope)
                           ? settings.neighbour_slope
                           : 0.0f),
      linear_fit_(settings.linear_fit),
      roots_{} {
  for (auto& tree : roots_)
    for (Node*& root : tree) root = new Node;
  const Bounds3& b = settings.bounds;
  double center[3] = {0, 0, 0};
  double edge = 0;
  if (!b.Empty() && IsFinite(b.lo) && IsFinite(b.hi)) {
    for (int k = 0; k < 3; ++k) {
      center[k] = 0.5 * (double(b.lo[k]) + double(b.hi[k]));
      edge = std::max(edge, double(b.hi[k]) - double(b.lo[k]));
    }
  }
  // Degenerate bounds (empty, non-finite, a single point) have no scale to go by: fall back to a
  // unit cube. As for any root, records outside it live in the root node; only speed suffers.
  if (!(edge > 0)) edge = 1;
  edge *= 1 + 2 * kRootPadding;
  for (int k = 0; k < 3; ++k) root_lo_[k] = center[k] - 0.5 * edge;
  grid_scale_ = kGridRes / edge;
}

IrradianceCache::~IrradianceCache() {
  for (auto& tree : roots_)
    for (Node* root : tree) {
      DeleteTree(root);
      delete root;
    }
}

int IrradianceCache::ClassOf(const Vec3& n) {
  int k = 0;
  if (std::fabs(n.y) > std::fabs(n[k])) k = 1;
  if (std::fabs(n.z) > std::fabs(n[k])) k = 2;
  return 2 * k + (n[k] < 0 ? 1 : 0);
}

unsigned IrradianceCache::ClassesNear(const Vec3& n, float a) {
  // Class (k, s) is the cone s v_k >= |v_j| (j != k), an intersection of four half-spaces
  // (s e_k -+ e_j) . v >= 0. A unit vector within angle t of that cone is within t of each
  // half-space: (s n_k -+ n_j) / sqrt(2) >= -sin t. With cos t = 1 - a^2, sin t = a sqrt(2 - a^2).
  // The margin covers float rounding in this test and in Ward's rule (n is unit up to ~1e-6);
  // NaN in n fails no comparison below, so every class is walked.
  const float aa = std::min(a, 1.0f);
  return ClassesWithinSin(n, std::sqrt(2.0f) * aa * std::sqrt(2.0f - aa * aa) + 1e-3f);
}

unsigned IrradianceCache::ClassesWithin(const Vec3& n, float angle) {
  if (!(angle < 0.5f * kPi)) return (1u << kClasses) - 1;
  return ClassesWithinSin(n, std::sqrt(2.0f) * std::sin(angle) + 1e-3f);
}

// The test of ClassesNear with (s n_k -+ n_j) >= -margin, margin = sqrt(2) sin t (+ rounding).
unsigned IrradianceCache::ClassesWithinSin(const Vec3& n, float margin) {
  const float bound = -margin;
  unsigned mask = 0;
  for (int k = 0; k < 3; ++k)
    for (int sign = 0; sign < 2; ++sign) {
      const float nk = sign ? -n[k] : n[k];
      bool near = true;
      for (int j = 0; j < 3; ++j) {
        if (j == k) continue;
        near &= !(nk - n[j] < bound) && !(nk + n[j] < bound);
      }
      if (near) mask |= 1u << (2 * k + sign);
    }
  return mask;
}

// Deletes node's children and blocks (not node itself: children come in groups of 8).
void IrradianceCache::DeleteTree(Node* node) {
  Node* children = node->children.load(std::memory_order_relaxed);
  if (children != nullptr) {
    for (int i = 0; i < 8; ++i) DeleteTree(&children[i]);  // recursion depth <= kMaxDepth
    delete[] children;
  }
  Block* b = node->head.load(std::memory_order_relaxed);
  while (b != nullptr) {
    Block* next = b->next;
    Block::Destroy(b);
    b = next;
  }
}

bool IrradianceCache::CellOf(const Vec3& x, uint32_t cell[3]) const {
  for (int k = 0; k < 3; ++k) {
    const double g = ToGrid(x[k], k);
    if (!(g >= 0 && g < kGridRes)) return false;
    cell[k] = uint32_t(g);
  }
  return true;
}

IrradianceCache::Block* IrradianceCache::Block::Create(int capacity, Block* next) {
  static_assert(sizeof(Block) % alignof(Cold) == 0 && (4 * sizeof(float) * 4) % alignof(Cold) == 0,
                "hot and cold arrays must be aligned after the header");
  static_assert(sizeof(Cold) == 48, "records must stay at most 64 bytes (16 hot + 48 cold)");
  static_assert(kMaxBlock <= 64, "slot index must fit in a RecordRef's low 6 bits and `ready`");
  void* memory = ::operator new(Bytes(capacity), std::align_val_t(kBlockAlign));
  Block* b = new (memory) Block;
  b->capacity = capacity;
  b->next = next;
  std::fill(b->hot(), b->hot() + 4 * capacity, 0.0f);
  for (int i = 0; i < capacity; ++i) new (&b->cold()[i]) Cold;
  return b;
}

void IrradianceCache::Block::Destroy(Block* b) {
  for (int i = 0; i < b->capacity; ++i) b->cold()[i].~Cold();
  b->~Block();
  ::operator delete(b, std::align_val_t(kBlockAlign));
}

void IrradianceCache::AddToNode(Node* node, const IrradianceRecord& r, std::atomic<uint64_t>* all) {
  // Writes r into slot i of b and makes it visible to lookups (radius last, release), then to
  // ForEach (push-front on the completion-order list).
  const auto fill = [&r, all](Block* b, int i) {
    Cold& c = b->cold()[i];
    b->x()[i] = r.position.x;
    b->y()[i] = r.position.y;
    b->z()[i] = r.position.z;
    b->radius()[i] = r.radius;
    c.normal = r.normal;
    c.irradiance = r.irradiance;
    c.origin = r.origin;
    c.level = r.level;
    c.occluder = PackOccluder(r.occluder);
    c.clamped.store(INFINITY, std::memory_order_relaxed);
    b->ready.fetch_or(uint64_t(1) << i, std::memory_order_release);
    const uint64_t ref = RefOf(b, i);
    uint64_t old = all->load(std::memory_order_relaxed);
    do {
      c.next_all = old;
    } while (!all->compare_exchange_weak(old, ref, std::memory_order_release,
                                         std::memory_order_relaxed));
  };
  Block* head = node->head.load(std::memory_order_acquire);
  for (;;) {
    if (head != nullptr) {
      const int i = head->claimed.fetch_add(1, std::memory_order_relaxed);
      if (i < head->capacity) {
        fill(head, i);
        return;
      }
    }
    // No block yet, or the newest one is full: push a new one holding r in slot 0.
    Block* fresh =
        Block::Create(head ? std::min(2 * head->capacity, kMaxBlock) : kFirstBlock, head);
    fresh->claimed.store(1, std::memory_order_relaxed);
    if (node->head.compare_exchange_strong(head, fresh, std::memory_order_acq_rel,
                                           std::memory_order_acquire)) {
      fill(fresh, 0);
      return;
    }
    // Another thread pushed a block first; `head` now holds it, so try that one.
    Block::Destroy(fresh);
  }
}

void IrradianceCache::GrowRadius(std::atomic<float>* max_radius, float radius) {
  float old = max_radius->load(std::memory_order_relaxed);
  while (old < radius && !max_radius->compare_exchange_weak(old, radius, std::memory_order_release,
                                                            std::memory_order_relaxed)) {
  }
}

template <typename F>
void IrradianceCache::ForEachNeighbour(int tree, const Vec3& x, float alpha, float beta,
                                       F f) const {
  // The octree walk of Lookup, simpler (once per insert, not per sample): a child is entered when
  // x lies in its cell grown by alpha * (its largest R) + beta (alpha >= 0, so no record of the
  // child reaches farther), and skipped when that is not positive.
  const double g[3] = {ToGrid(x.x, 0), ToGrid(x.y, 1), ToGrid(x.z, 2)};
  const double scale = grid_scale_;
  struct Item {
    const Node* node;
    double lo[3];
    int depth;
  };
  Item stack[kLookupStack];
  int top = 0;
  for (const Node* root : roots_[tree]) stack[top++] = Item{root, {0, 0, 0}, 0};
  while (top > 0) {
    const Item item = stack[--top];
    // Records at shallow nodes (large R) are scanned by every walk that passes: 4 at a time on
    // the hot arrays, f only on the records within reach.
    ForEachWithin(item.node->head.load(std::memory_order_acquire), x, alpha, beta, f);
    if (item.depth == kMaxDepth) continue;
    const Node* children = item.node->children.load(std::memory_order_acquire);
    if (children == nullptr) continue;
    const double half = double(1u << (kMaxDepth - 1 - item.depth));
    for (int i = 0; i < 8; ++i) {
      const float child_radius = item.node->child_radius[i].load(std::memory_order_acquire);
      if (!(child_radius > 0)) continue;
      const float distance = alpha * child_radius + beta;
      if (!(distance > 0)) continue;
      const double grow = double(distance) * scale + 1.0;
      Item next{&children[i], {0, 0, 0}, item.depth + 1};
      bool enter = true;
      for (int k = 0; k < 3; ++k) {
        next.lo[k] = item.lo[k] + (((i >> k) & 1) ? half : 0.0);
        enter &= g[k] >= next.lo[k] - grow && g[k] <= next.lo[k] + half + grow;
      }
      if (enter) stack[top++] = next;
    }
  }
}

// A neighbour j lowers r's radius only when R_j + slope d < R, so only within d < R / slope; and
// r lowers j's only when R + slope d < R_j, so only within d < (R_j - R) / slope, in subtrees
// whose largest R_j exceeds R. The walks enter only those subtrees and test the distances 4 at a
// time before anything else (the same result as testing every record; measured on living-room,
// the clamp's walk over max(R, R_j) / slope calling a test per record was 7% of a render).
float IrradianceCache::ClampToNeighbours(const IrradianceRecord& r) const {
  float radius = r.radius;
  const float slack = float(1 + kReachSlack);
  ForEachNeighbour(TreeOf(r.level), r.position, 0.0f, r.radius / neighbour_slope_ * slack,
                   [&](const Block* b, int i) {
                     const Vec3 xj(b->x()[i], b->y()[i], b->z()[i]);
                     const float rj = std::min(
                         b->radius()[i], b->cold()[i].clamped.load(std::memory_order_relaxed));
                     radius = std::min(radius, rj + neighbour_slope_ * Length(xj - r.position));
                   });
  return radius;
}

namespace {

// Lowers a record's clamped radius to `bound` if that is lower, with a CAS loop: concurrent
// inserts may both lower one record.
void LowerClamped(std::atomic<float>& clamped, float bound) {
  float old = clamped.load(std::memory_order_relaxed);
  while (bound < old && !clamped.compare_exchange_weak(old, bound, std::memory_order_relaxed)) {
  }
}

}  // namespace

void IrradianceCache::LowerNeighbours(const IrradianceRecord& r) const {
  const float slack = float(1 + kReachSlack);
  ForEachNeighbour(TreeOf(r.level), r.position, slack / neighbour_slope_,
                   -r.radius / neighbour_slope_ * slack, [&](const Block* b, int i) {
                     const Vec3 xj(b->x()[i], b->y()[i], b->z()[i]);
                     const float bound = r.radius + neighbour_slope_ * Length(xj - r.position);
                     if (!(bound < b->radius()[i])) return;
                     LowerClamped(const_cast<Block*>(b)->cold()[i].clamped, bound);
                   });
}

void IrradianceCache::LowerOwn(const IrradianceRecord& r, float bound) const {
  // Records at r's very position (the walk squares its reach: 1e-12 stays a normal float).
  ForEachNeighbour(TreeOf(r.level), r.position, 0.0f, 1e-12f, [&](const Block* b, int i) {
    if (b->radius()[i] != r.radius || b->x()[i] != r.position.x || b->y()[i] != r.position.y ||
        b->z()[i] != r.position.z)
      return;
    LowerClamped(const_cast<Block*>(b)->cold()[i].clamped, bound);
  });
}

void IrradianceCache::Insert(const IrradianceRecord& in) {
  if (!IsValidRecord(in)) return;
  IrradianceRecord r = in;
  // Unit normals only (valid ones are within 1e-3 of it): the normal term 1 - n . n_i and the
  // octree's normal classes assume it. Records made here are unit already and kept bit for bit.
  if (std::abs(LengthSquared(r.normal) - 1.0f) > 1e-6f) r.normal = Normalize(r.normal);
  if (neighbour_slope_ > 0) r.radius = ClampToNeighbours(r);
  InsertUnclamped(r);
  if (neighbour_slope_ > 0) {
    // Published, then one read-modify-write of a counter every insert shares, then clamped again
    // against what is published now, and its neighbours lowered: of two records inserted at once
    // the later RMW reads the earlier one's (acquire / release on one location), so that insert
    // sees the other's record, whichever order they land in (a fence would do the same; GCC's
    // ThreadSanitizer does not take fences). Without the second clamp a big record clamped
    // before a small one near it was published kept its radius
    // (NeighbourClampingHoldsForConcurrentInserts: 4498 of 20000 pairs).
    inserts_published_.fetch_add(1, std::memory_order_acq_rel);
    const float again = ClampToNeighbours(r);
    if (again < r.radius) LowerOwn(r, again);
    LowerNeighbours(r);
  }
  // Counted last, with release: a lookup region gathered after it saw this count (acquire) holds
  // the record and every radius it lowered, and one gathered before sees a new count and gathers
  // again (LookupNear keeps the clamped radii it gathered).
  size_.fetch_add(1, std::memory_order_release);
}

void IrradianceCache::InsertUnclamped(const IrradianceRecord& r) {
  Node* node = roots_[TreeOf(r.level)][ClassOf(r.normal)];
  uint32_t cell[3];
  if (CellOf(r.position, cell)) {
    // Deepest level whose cells (2^shift grid units) are at least kCellPerReach reaches wide.
    const double reach = double(max_accuracy_) * double(r.radius) * grid_scale_;
    int shift = 0;
    while (shift < kMaxDepth && std::ldexp(1.0, shift) < kCellPerReach * reach) ++shift;
    const int depth = kMaxDepth - shift;
    for (int d = 0; d < depth; ++d) {
      Node* children = node->children.load(std::memory_order_acquire);
      if (children == nullptr) {
        // A leaf keeps the first kSplitAfter records that would go deeper (still correct: its
        // cell contains them and its radius bound covers them), so isolated small records do not
        // each get a chain of nodes down to their own level.
        if (node->deeper.fetch_add(1, std::memory_order_relaxed) < kSplitAfter) break;
        Node* fresh = new Node[8];
        // The loser of a race deletes its group and uses the winner's (acquire makes it
        // readable).
        if (node->children.compare_exchange_strong(children, fresh, std::memory_order_acq_rel,
                                                   std::memory_order_acquire)) {
          children = fresh;
        } else {
          delete[] fresh;
        }
      }
      const int bit = kMaxDepth - 1 - d;
      const int index =
          ((cell[0] >> bit) & 1) | (((cell[1] >> bit) & 1) << 1) | (((cell[2] >> bit) & 1) << 2);
      // Grown before the record is published, so a lookup that can see the record can enter the
      // child (release here, acquire in Lookup).
      GrowRadius(&node->child_radius[index], r.radius);
      node = &children[index];
    }
  }
  // Records outside the root cube stay in the root node, which every lookup scans.
  AddToNode(node, r, &all_);
}

template <typename F>
void IrradianceCache::WalkNodes(const Vec3& x, unsigned classes, int max_level, float reach_scale,
                                float extra, F visit) const {
  // x on the grid; may lie outside [0, 2^20) (records inside the root cube can reach points
  // outside it) or be NaN (then no child test passes and only the roots are visited).
  const double g[3] = {ToGrid(x.x, 0), ToGrid(x.y, 1), ToGrid(x.z, 2)};
  // The child test runs in float, so it is made conservative by a margin above float rounding of
  // grid coordinates (< 2^20, so within 2^-4 units) and of the product below: visiting a node
  // too many costs time only, since every candidate is tested by the exact rule.
  const float gx[3] = {float(g[0]), float(g[1]), float(g[2])};
  const float margin = 1.0f + extra;  // grid units
  struct Item {
    const Node* node;
    float lo[3];  // cell's low corner, grid units (exact: integers < 2^24)
    int depth;
  };
  Item stack[kLookupStack];
  int top = 0;
  for (int t = TreeOf(std::max(0, max_level)); t >= 0; --t)
    for (unsigned c = classes; c != 0; c &= c - 1)
      stack[top++] = Item{roots_[t][__builtin_ctz(c)], {0, 0, 0}, 0};
  while (top > 0) {
    // Copied field by field, with the widths they were stored with: a whole-struct copy right
    // after the field stores below fails store-to-load forwarding and stalls.
    --top;
    Item item;
    item.node = stack[top].node;
    for (int k = 0; k < 3; ++k) item.lo[k] = stack[top].lo[k];
    item.depth = stack[top].depth;
    if (const Block* head = item.node->head.load(std::memory_order_acquire)) visit(head);
    if (item.depth == kMaxDepth) continue;
    const Node* children = item.node->children.load(std::memory_order_acquire);
    if (children == nullptr) continue;
    const float half = float(1u << (kMaxDepth - 1 - item.depth));  // child cell edge, grid units
    float mid[3];
    for (int k = 0; k < 3; ++k) mid[k] = item.lo[k] + half;
    // Child i (bit k of i: the upper half on axis k) is entered when it holds records (largest R
    // above 0) and x lies in its cell grown by grow_i = R_i * reach_scale + margin on every axis.
    // Branch-free (which children a lookup enters is data dependent, and mispredicted branches
    // were most of the walk's cost), all eight children at once with SSE in the same float
    // operations as the scalar test, so the same children are entered either way.
    float radius[8];
    for (int i = 0; i < 8; ++i)
      radius[i] = item.node->child_radius[i].load(std::memory_order_acquire);
    const unsigned enter = EnterChildren(radius, gx, item.lo, mid, half, reach_scale, margin);
    // Pushed in ascending child order, as before: the order the records are summed in.
    for (unsigned m = enter; m != 0; m &= m - 1) {
      const int i = __builtin_ctz(m);
      Item& next = stack[top++];
      next.node = &children[i];
      next.depth = item.depth + 1;
      for (int k = 0; k < 3; ++k) next.lo[k] = ((i >> k) & 1) ? mid[k] : item.lo[k];
    }
  }
}

bool IrradianceCache::Lookup(const Vec3& x, const Vec3& n, float a, Vec3* irradiance,
                             LookupInfo* info, int max_level, float narrow_a) const {
  Accumulator acc{x, n, std::min(a, max_accuracy_), max_level, narrow_a, linear_fit_};
  const float reach_scale = float(double(acc.a) * grid_scale_ * (1 + kReachSlack));
  // The walk only collects the record blocks of the nodes it enters, prefetching each, and scans
  // them afterwards: the cache misses on blocks then overlap each other and the walk instead of
  // stalling it one by one. More than kHeads heads (rare) are scanned as they come.
  constexpr int kHeads = 64;
  const Block* heads[kHeads];
  int num_heads = 0;
  WalkNodes(x, ClassesNear(n, acc.a), max_level, reach_scale, 0.0f, [&](const Block* head) {
    if (num_heads < kHeads) {
      __builtin_prefetch(head);
      heads[num_heads++] = head;
    } else {
      acc.Scan(head);
    }
  });
  for (int i = 0; i < num_heads; ++i) acc.Scan(heads[i]);
  return acc.Finish(irradiance, info);
}

void IrradianceCache::Gather(const Vec3& x, const Vec3& n, float a, float radius, float angle,
                             int max_level, LookupRegion* region) const {
  region->center = x;
  region->normal = n;
  region->radius = radius;
  region->cos_angle = std::cos(angle);
  region->a = a;
  region->max_level = max_level;
  region->cache = this;
  region->generation = size_.load(std::memory_order_acquire);
  region->count = 0;
  // A record can count at (x', n') with |x' - x| <= radius and angle(n', n) <= angle only if
  // |x - x_i| < a R_i + radius and angle(n, n_i) < acos(1 - a^2) + angle (triangle inequalities;
  // the slack covers float rounding here and in the rule).
  const float limit = std::acos(std::max(-1.0f, 1 - a * a)) + angle + 1e-3f;
  const float min_dot = limit < kPi ? std::cos(limit) : -1.0f;
  const float slack = 1 + 1e-4f;
  const float reach_scale = float(double(a) * grid_scale_ * (1 + kReachSlack));
  const float extra = float(double(radius) * grid_scale_ * (1 + kReachSlack));
  WalkNodes(x, ClassesWithin(n, limit), max_level, reach_scale, extra, [&](const Block* head) {
    if (region->count < 0) return;
    ForEachWithin(head, x, a * slack, radius * slack, [&](const Block* b, int i) {
      const Cold& c = b->cold()[i];
      if (region->count < 0 || c.level > max_level || !(Dot(n, c.normal) > min_dot)) return;
      if (region->count == LookupRegion::kMaxRecords) {
        region->count = -1;
        return;
      }
      const int k = region->count++;
      region->refs[k] = RefOf(b, i);
      region->x[k] = b->x()[i];
      region->y[k] = b->y()[i];
      region->z[k] = b->z()[i];
      region->r[k] = std::min(b->radius()[i], c.clamped.load(std::memory_order_relaxed));
      region->nx[k] = c.normal.x;
      region->ny[k] = c.normal.y;
      region->nz[k] = c.normal.z;
      const Vec3 o = UnpackOccluder(c.occluder);
      region->ox[k] = o.x;
      region->oy[k] = o.y;
      region->oz[k] = o.z;
      region->o2[k] = LengthSquared(o);
      region->ex[k] = c.irradiance.x;
      region->ey[k] = c.irradiance.y;
      region->ez[k] = c.irradiance.z;
      region->remote[k] = c.origin != 0;
    });
  });
  // Pads the arrays to whole groups of 4 with points that reach nowhere (R = 0).
  for (int k = std::max(0, region->count); k % 4 != 0; ++k) {
    region->x[k] = region->y[k] = region->z[k] = region->r[k] = 0;
    region->nx[k] = region->ny[k] = region->nz[k] = 0;
    region->ox[k] = region->oy[k] = region->oz[k] = region->o2[k] = 0;
  }
}

// Inlined: called once per group of a region lookup, where a call cost 10% of the lookup.
[[gnu::always_inline]] inline void IrradianceCache::RegionWeights4(const LookupRegion& g, int k0,
                                                                   const Vec3& x, const Vec3& n,
                                                                   float a, float w[4]) {
#if defined(__SSE2__)
  // RecordWeight's tests and arithmetic, in its order of operations (SSE does not fuse
  // multiply-adds; _mm_max_ps(v, 0) and _mm_min_ps(1e3, v) pick as std::max(0, v) and
  // std::min(v, 1e3) do, NaN included).
  const auto load = [k0](const float* p) { return _mm_load_ps(p + k0); };
  const __m128 zero = _mm_setzero_ps(), va = _mm_set1_ps(a), vr = load(g.r);
  const __m128 nx = load(g.nx), ny = load(g.ny), nz = load(g.nz);
  const __m128 ndot =
      _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_set1_ps(n.x), nx), _mm_mul_ps(_mm_set1_ps(n.y), ny)),
                 _mm_mul_ps(_mm_set1_ps(n.z), nz));
  const __m128 dx = _mm_sub_ps(_mm_set1_ps(x.x), load(g.x));
  const __m128 dy = _mm_sub_ps(_mm_set1_ps(x.y), load(g.y));
  const __m128 dz = _mm_sub_ps(_mm_set1_ps(x.z), load(g.z));
  const __m128 d2 =
      _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
  const __m128 reach = _mm_mul_ps(va, vr);
  __m128 ok = _mm_and_ps(_mm_cmpgt_ps(ndot, zero), _mm_cmplt_ps(d2, _mm_mul_ps(reach, reach)));
  const __m128 od = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, load(g.ox)), _mm_mul_ps(dy, load(g.oy))),
                               _mm_mul_ps(dz, load(g.oz)));
  ok = _mm_and_ps(ok, _mm_cmpngt_ps(od, load(g.o2)));
  const __m128 eps = _mm_add_ps(_mm_div_ps(_mm_sqrt_ps(d2), vr),
                                _mm_sqrt_ps(_mm_max_ps(_mm_sub_ps(_mm_set1_ps(1.0f), ndot), zero)));
  ok = _mm_and_ps(ok, _mm_cmplt_ps(eps, va));
  const __m128 half = _mm_set1_ps(0.5f);
  const __m128 mx = _mm_mul_ps(_mm_add_ps(_mm_set1_ps(n.x), nx), half);
  const __m128 my = _mm_mul_ps(_mm_add_ps(_mm_set1_ps(n.y), ny), half);
  const __m128 mz = _mm_mul_ps(_mm_add_ps(_mm_set1_ps(n.z), nz), half);
  const __m128 px = _mm_sub_ps(load(g.x), _mm_set1_ps(x.x));
  const __m128 py = _mm_sub_ps(load(g.y), _mm_set1_ps(x.y));
  const __m128 pz = _mm_sub_ps(load(g.z), _mm_set1_ps(x.z));
  const __m128 front =
      _mm_add_ps(_mm_add_ps(_mm_mul_ps(px, mx), _mm_mul_ps(py, my)), _mm_mul_ps(pz, mz));
  ok = _mm_and_ps(ok, _mm_cmpngt_ps(front, _mm_mul_ps(_mm_set1_ps(kInFrontTolerance * a), vr)));
  const __m128 weight = _mm_min_ps(_mm_set1_ps(kWardMaxWeight), _mm_div_ps(_mm_set1_ps(1.0f), eps));
  _mm_storeu_ps(w, _mm_and_ps(ok, weight));
#else
  for (int l = 0; l < 4; ++l) {
    const int k = k0 + l;
    IrradianceRecord rec;
    rec.position = Vec3(g.x[k], g.y[k], g.z[k]);
    rec.normal = Vec3(g.nx[k], g.ny[k], g.nz[k]);
    rec.radius = g.r[k];
    rec.occluder = Vec3(g.ox[k], g.oy[k], g.oz[k]);
    w[l] = g.r[k] > 0 ? RecordWeight(x, n, a, rec) : 0.0f;
  }
#endif
}

bool IrradianceCache::LookupNear(const Vec3& x, const Vec3& n, float a, float radius, float angle,
                                 LookupRegion* region, Vec3* irradiance, LookupInfo* info,
                                 int max_level, float narrow_a) const {
  a = std::min(a, max_accuracy_);
  const auto covers = [&] {
    return region->cache == this && region->a == a && region->max_level == max_level &&
           region->generation == size_.load(std::memory_order_acquire) &&
           LengthSquared(x - region->center) <= region->radius * region->radius &&
           Dot(n, region->normal) >= region->cos_angle;
  };
  const bool reused = covers();
  if (!reused) {
    if (!(radius >= 0) || !(angle >= 0) || !IsFinite(x) || !IsFinite(n)) {
      region->cos_angle = 2;  // nothing to gather around: an empty region
      return Lookup(x, n, a, irradiance, info, max_level, narrow_a);
    }
    Gather(x, n, a, radius, angle, max_level, region);
  }
  if (region->count < 0) return Lookup(x, n, a, irradiance, info, max_level, narrow_a);
  Accumulator acc{x, n, a, max_level, narrow_a, linear_fit_};
  // Squared-distance reject on the copied hot parts (RecordWeight's expression: never rejects a
  // record the rule counts), then the full rule on the few within reach.
  for (int k0 = 0; k0 < region->count; k0 += 4) {
    const int near =
        WithinReach4(region->x + k0, region->y + k0, region->z + k0, region->r + k0, x, a, 0.0f);
    if (near == 0) continue;
    float w[4];
    RegionWeights4(*region, k0, x, n, a, w);
    for (int m = near; m != 0; m &= m - 1) {
      const int l = __builtin_ctz(m), k = k0 + l;
      if (w[l] > 0) {
        acc.Take(w[l], Vec3(region->ex[k], region->ey[k], region->ez[k]), region->remote[k],
                 Vec3(region->x[k], region->y[k], region->z[k]));
        acc.Narrow(w[l], Vec3(region->x[k], region->y[k], region->z[k]),
                   Vec3(region->nx[k], region->ny[k], region->nz[k]), region->r[k],
                   Vec3(region->ex[k], region->ey[k], region->ez[k]));
      }
    }
  }
  const bool found = acc.Finish(irradiance, info);
  if (info != nullptr) info->from_region = reused;
  return found;
}

bool IrradianceCache::LookupBruteForce(const Vec3& x, const Vec3& n, float a, Vec3* irradiance,
                                       LookupInfo* info, int max_level, float narrow_a) const {
  Accumulator acc{x, n, std::min(a, max_accuracy_), max_level, narrow_a, linear_fit_};
  ForEach([&acc](const IrradianceRecord& r) { acc.Add(r); });
  return acc.Finish(irradiance, info);
}

void IrradianceCache::AddMemory(const Node* node, CacheMemory* m) {
  const Node* children = node->children.load(std::memory_order_acquire);
  if (children != nullptr) {
    m->nodes += 8;
    m->octree_bytes += 8 * sizeof(Node);
    for (int i = 0; i < 8; ++i) AddMemory(&children[i], m);
  }
  for (const Block* b = node->head.load(std::memory_order_acquire); b != nullptr; b = b->next) {
    const size_t filled = size_t(__builtin_popcountll(b->ready.load(std::memory_order_acquire)));
    m->records += filled;
    m->record_bytes += filled * kRecordBytes;
    m->octree_bytes += Block::Bytes(b->capacity) - filled * kRecordBytes;
  }
}

CacheMemory IrradianceCache::MemoryUse() const {
  CacheMemory m;
  m.bytes_per_record = kRecordBytes;
  m.nodes = kTrees * kClasses;
  m.octree_bytes = m.nodes * sizeof(Node);
  for (const auto& tree : roots_)
    for (const Node* root : tree) AddMemory(root, &m);
  return m;
}

}  // namespace irfarm
