// Lock-free octree irradiance cache; see irradiance_cache.h for the layout and its invariants.
#include "cache/irradiance_cache.h"

#include <algorithm>
#include <cmath>
#include <new>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "cache/irradiance_weight.h"

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

}  // namespace

// Running sums of one lookup; in double so that many records of very different weight (1/a up to
// kWardMaxWeight) sum without loss.
struct IrradianceCache::Accumulator {
  Vec3 x, n;
  float a;
  int max_level;
  double weight = 0, weight_sq = 0;
  double e[3] = {0, 0, 0};
  int count = 0;
  int remote = 0;  // counted records with origin != 0
  static constexpr int kPending = 32;
  uint64_t pending[kPending];  // RecordRefs of records within reach not weighed yet
  int pending_count = 0;

  void Add(const IrradianceRecord& r) {
    if (r.level > max_level) return;
    const float w = RecordWeight(x, n, a, r);
    if (w > 0) {
      weight += w;
      weight_sq += double(w) * w;
      for (int k = 0; k < 3; ++k) e[k] += double(w) * r.irradiance[k];
      ++count;
      if (r.origin != 0) ++remote;
    }
  }
  // Scans the ready slots of one node's blocks: squared-distance reject on the hot part, the full
  // rule (RecordWeight, the same as brute force) on the few records within reach.
  void Scan(const Block* head) {
    for (const Block* b = head; b != nullptr; b = b->next) {
      const uint64_t ready = b->ready.load(std::memory_order_acquire);
      if (ready == 0) continue;
      // Branch-free pass over the hot arrays, then the rule on the few hits: a mispredicted branch
      // per candidate would cost more than the test itself.
      const int end = 64 - __builtin_clzll(ready);  // past the last ready slot
      uint64_t hits = 0;
      for (int i = 0; i < end; i += 4) {
        const uint64_t group = (ready >> i) & 0xF;
        if (group == 0xF) {
          hits |= uint64_t(Within4(b, i)) << i;
        } else {
          for (uint64_t g = group; g != 0; g &= g - 1) {
            const int j = i + __builtin_ctzll(g);
            hits |= uint64_t(Within1(b, j)) << j;
          }
        }
      }
      for (; hits != 0; hits &= hits - 1) Defer(b, __builtin_ctzll(hits));
    }
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
  // |x - x_j|^2 < (a R_j)^2 for ready slot j, in the same float expression as RecordWeight's
  // distance test, so that it never rejects a record the rule would count.
  bool Within1(const Block* b, int j) const {
    const float dx = x.x - b->x()[j], dy = x.y - b->y()[j], dz = x.z - b->z()[j];
    const float reach = a * b->radius()[j];
    return dx * dx + dy * dy + dz * dz < reach * reach;
  }
  // The same for ready slots i..i+3, as a 4-bit mask; identical operations and rounding (SSE does
  // not fuse multiply-adds).
  int Within4(const Block* b, int i) const {
#if defined(__SSE2__)
    const __m128 dx = _mm_sub_ps(_mm_set1_ps(x.x), _mm_loadu_ps(b->x() + i));
    const __m128 dy = _mm_sub_ps(_mm_set1_ps(x.y), _mm_loadu_ps(b->y() + i));
    const __m128 dz = _mm_sub_ps(_mm_set1_ps(x.z), _mm_loadu_ps(b->z() + i));
    const __m128 reach = _mm_mul_ps(_mm_set1_ps(a), _mm_loadu_ps(b->radius() + i));
    const __m128 d2 =
        _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
    return _mm_movemask_ps(_mm_cmplt_ps(d2, _mm_mul_ps(reach, reach)));
#else
    int mask = 0;
    for (int k = 0; k < 4; ++k) mask |= int(Within1(b, i + k)) << k;
    return mask;
#endif
  }
  bool Finish(Vec3* irradiance, LookupInfo* info) {
    Flush();
    if (info != nullptr) {
      info->records_used = count;
      info->weight_sum = float(weight);
      info->weight_sq_sum = float(weight_sq);
      info->remote_records_used = remote;
      info->from_region = false;
    }
    if (count == 0) return false;
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
    for (const Block* b = item.node->head.load(std::memory_order_acquire); b != nullptr;
         b = b->next) {
      const uint64_t ready = b->ready.load(std::memory_order_acquire);
      // Records at shallow nodes (large R) are scanned by every walk that passes: the distance
      // test runs 4 at a time on the hot arrays, and f only on the records within reach. Only
      // ready slots are read (as Accumulator::Scan): a group of 4 all ready at once, the ready
      // ones of a partial group one by one; a slot not yet ready may be being written by another
      // thread's insert (a data race, found by ThreadSanitizer in the worker, where records from
      // the coordinator are inserted while the render inserts its own).
      uint64_t hits = 0;
      const int end = ready == 0 ? 0 : 64 - __builtin_clzll(ready);
      const auto within1 = [&](int j) {
        const Vec3 d(x.x - b->x()[j], x.y - b->y()[j], x.z - b->z()[j]);
        const float reach = alpha * b->radius()[j] + beta;
        return reach > 0 && LengthSquared(d) < reach * reach;
      };
      for (int i = 0; i < end; i += 4) {
        const uint64_t group = (ready >> i) & 0xF;
        int mask = 0;
        if (group != 0xF) {
          for (uint64_t g = group; g != 0; g &= g - 1) {
            const int j = i + __builtin_ctzll(g);
            mask |= int(within1(j)) << (j - i);
          }
        } else {
#if defined(__SSE2__)
          const __m128 dx = _mm_sub_ps(_mm_set1_ps(x.x), _mm_loadu_ps(b->x() + i));
          const __m128 dy = _mm_sub_ps(_mm_set1_ps(x.y), _mm_loadu_ps(b->y() + i));
          const __m128 dz = _mm_sub_ps(_mm_set1_ps(x.z), _mm_loadu_ps(b->z() + i));
          const __m128 reach = _mm_add_ps(
              _mm_mul_ps(_mm_set1_ps(alpha), _mm_loadu_ps(b->radius() + i)), _mm_set1_ps(beta));
          const __m128 d2 =
              _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
          mask = _mm_movemask_ps(_mm_and_ps(_mm_cmpgt_ps(reach, _mm_setzero_ps()),
                                            _mm_cmplt_ps(d2, _mm_mul_ps(reach, reach))));
#else
          for (int k = 0; k < 4; ++k) mask |= int(within1(i + k)) << k;
#endif
        }
        hits |= uint64_t(mask) << i;
      }
      for (hits &= ready; hits != 0; hits &= hits - 1) f(b, __builtin_ctzll(hits));
    }
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

void IrradianceCache::LowerNeighbours(const IrradianceRecord& r) const {
  const float slack = float(1 + kReachSlack);
  ForEachNeighbour(
      TreeOf(r.level), r.position, slack / neighbour_slope_, -r.radius / neighbour_slope_ * slack,
      [&](const Block* b, int i) {
        const Vec3 xj(b->x()[i], b->y()[i], b->z()[i]);
        const float bound = r.radius + neighbour_slope_ * Length(xj - r.position);
        if (!(bound < b->radius()[i])) return;
        // Lowered only, with a CAS loop: concurrent inserts may both lower one record.
        std::atomic<float>& c = const_cast<Block*>(b)->cold()[i].clamped;
        float old = c.load(std::memory_order_relaxed);
        while (bound < old && !c.compare_exchange_weak(old, bound, std::memory_order_relaxed)) {
        }
      });
}

void IrradianceCache::Insert(const IrradianceRecord& in) {
  if (!IsValidRecord(in)) return;
  IrradianceRecord r = in;
  if (neighbour_slope_ > 0) r.radius = ClampToNeighbours(r);
  InsertUnclamped(r);
  if (neighbour_slope_ > 0) LowerNeighbours(r);
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
  size_.fetch_add(1, std::memory_order_relaxed);
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
    float grow;   // reach_scale * (largest R_i in the subtree) + margin, grid units
    int depth;
  };
  Item stack[kLookupStack];
  int top = 0;
  for (int t = TreeOf(std::max(0, max_level)); t >= 0; --t)
    for (unsigned c = classes; c != 0; c &= c - 1)
      stack[top++] = Item{roots_[t][__builtin_ctz(c)], {0, 0, 0}, INFINITY, 0};
  while (top > 0) {
    // Copied field by field, with the widths they were stored with: a whole-struct copy right
    // after the field stores below fails store-to-load forwarding and stalls.
    --top;
    Item item;
    item.node = stack[top].node;
    for (int k = 0; k < 3; ++k) item.lo[k] = stack[top].lo[k];
    item.grow = stack[top].grow;
    item.depth = stack[top].depth;
    if (const Block* head = item.node->head.load(std::memory_order_acquire)) visit(head);
    if (item.depth == kMaxDepth) continue;
    const Node* children = item.node->children.load(std::memory_order_acquire);
    if (children == nullptr) continue;
    const float half = float(1u << (kMaxDepth - 1 - item.depth));  // child cell edge, grid units
    // Children no record of this subtree can reach from x (their radii are <= the subtree's):
    // per axis, the lower half is out when x is beyond mid + grow, the upper when below
    // mid - grow. Bit i of `maybe` is child i.
    static constexpr unsigned kLowerHalf[3] = {0x55, 0x33, 0x0F};
    unsigned maybe = 0xFF;
    float mid[3];
    // Branch-free: which children a lookup enters is data dependent, and mispredicted branches
    // were most of the walk's cost.
    for (int k = 0; k < 3; ++k) {
      mid[k] = item.lo[k] + half;
      maybe &= ~(kLowerHalf[k] & (0u - unsigned(gx[k] > mid[k] + item.grow)));
      maybe &= kLowerHalf[k] | (0u - unsigned(!(gx[k] < mid[k] - item.grow)));
    }
    for (; maybe != 0; maybe &= maybe - 1) {
      const int i = __builtin_ctz(maybe);
      const float radius = item.node->child_radius[i].load(std::memory_order_acquire);
      const float grow = radius * reach_scale + margin;
      Item& next = stack[top];
      next.node = &children[i];
      next.grow = grow;
      next.depth = item.depth + 1;
      bool enter = radius > 0;  // else an empty child
      for (int k = 0; k < 3; ++k) {
        next.lo[k] = ((i >> k) & 1) ? mid[k] : item.lo[k];
        enter &= (gx[k] >= next.lo[k] - grow) & (gx[k] <= next.lo[k] + half + grow);
      }
      top += enter;
    }
  }
}

bool IrradianceCache::Lookup(const Vec3& x, const Vec3& n, float a, Vec3* irradiance,
                             LookupInfo* info, int max_level) const {
  Accumulator acc{x, n, std::min(a, max_accuracy_), max_level};
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
    for (const Block* b = head; b != nullptr; b = b->next) {
      const uint64_t ready = b->ready.load(std::memory_order_acquire);
      for (uint64_t bits = ready; bits != 0; bits &= bits - 1) {
        const int i = __builtin_ctzll(bits);
        const float dx = x.x - b->x()[i], dy = x.y - b->y()[i], dz = x.z - b->z()[i];
        const float reach = (a * b->radius()[i] + radius) * slack;
        if (!(dx * dx + dy * dy + dz * dz < reach * reach)) continue;
        const Cold& c = b->cold()[i];
        if (c.level > max_level || !(Dot(n, c.normal) > min_dot)) continue;
        if (region->count == LookupRegion::kMaxRecords) {
          region->count = -1;
          return;
        }
        const int k = region->count++;
        region->refs[k] = RefOf(b, i);
        region->x[k] = b->x()[i];
        region->y[k] = b->y()[i];
        region->z[k] = b->z()[i];
        region->r[k] = b->radius()[i];
      }
    }
  });
}

bool IrradianceCache::LookupNear(const Vec3& x, const Vec3& n, float a, float radius, float angle,
                                 LookupRegion* region, Vec3* irradiance, LookupInfo* info,
                                 int max_level) const {
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
      return Lookup(x, n, a, irradiance, info, max_level);
    }
    Gather(x, n, a, radius, angle, max_level, region);
  }
  if (region->count < 0) return Lookup(x, n, a, irradiance, info, max_level);
  Accumulator acc{x, n, a, max_level};
  // Squared-distance reject on the copied hot parts (Within4's expression: never rejects a record
  // the rule counts), then the full rule on the few within reach.
  for (int k = 0; k < region->count; ++k) {
    const float dx = x.x - region->x[k], dy = x.y - region->y[k], dz = x.z - region->z[k];
    const float reach = a * region->r[k];
    if (!(dx * dx + dy * dy + dz * dz < reach * reach)) continue;
    const uint64_t ref = region->refs[k];
    acc.Add(BlockOf(ref)->Record(SlotOf(ref)));
  }
  const bool found = acc.Finish(irradiance, info);
  if (info != nullptr) info->from_region = reused;
  return found;
}

bool IrradianceCache::LookupBruteForce(const Vec3& x, const Vec3& n, float a, Vec3* irradiance,
                                       LookupInfo* info, int max_level) const {
  Accumulator acc{x, n, std::min(a, max_accuracy_), max_level};
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
