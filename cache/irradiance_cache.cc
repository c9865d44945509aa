// Lock-free octree irradiance cache; see irradiance_cache.h for the layout and its invariants.
#include "cache/irradiance_cache.h"

#include <algorithm>
#include <cmath>
#include <new>

#include "cache/irradiance_weight.h"

namespace irfarm {
namespace {

constexpr double kGridRes = double(1u << 20);  // cells per axis at the deepest level

// The root cube extends the scene bounds by this fraction of their largest extent on every side,
// so that the validity boxes of records on the scene's outer walls (a_max * R_i, typically well
// under a quarter of the scene) still fit inside it. Records that do not fit go to the root
// node, which every lookup scans, so this only matters for speed, never for correctness.
constexpr double kRootPadding = 0.25;

// Relative slack on a record's reach a_max * R_i. RecordWeight only counts a record when the
// float |x - x_i| < a * R_i, which bounds the true distance by a * R_i * (1 + ~1e-6) (a few
// roundings); 1e-4 covers that with margin. Box corners are then computed in double from float
// inputs, and the grid mapping is monotone, so containment carries over exactly.
constexpr double kReachSlack = 1e-4;

}  // namespace

// Running sums of one lookup; in double so that many records of very different weight (1/a up to
// kWardMaxWeight) sum without loss.
struct IrradianceCache::Accumulator {
  Vec3 x, n;
  float a;
  double weight = 0;
  double e[3] = {0, 0, 0};
  int count = 0;
  int remote = 0;  // counted records with origin != 0

  void Add(const IrradianceRecord& r) {
    const float w = RecordWeight(x, n, a, r);
    if (w > 0) {
      weight += w;
      for (int k = 0; k < 3; ++k) e[k] += double(w) * r.irradiance[k];
      ++count;
      if (r.origin != 0) ++remote;
    }
  }
  bool Finish(Vec3* irradiance, LookupInfo* info) const {
    if (info != nullptr) {
      info->records_used = count;
      info->weight_sum = float(weight);
      info->remote_records_used = remote;
    }
    if (count == 0) return false;
    *irradiance = Vec3(float(e[0] / weight), float(e[1] / weight), float(e[2] / weight));
    return true;
  }
};

IrradianceCache::Node::Node() {
  for (auto& c : children) c.store(nullptr, std::memory_order_relaxed);
  head.store(nullptr, std::memory_order_relaxed);
}

IrradianceCache::IrradianceCache(const CacheSettings& settings)
    // NaN or a <= 0 become 0: records then reach nowhere and no lookup ever succeeds.
    : max_accuracy_(settings.max_accuracy > 0 ? std::min(settings.max_accuracy, 1.0f) : 0.0f),
      root_(new Node) {
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
  const Entry* e = all_.load(std::memory_order_acquire);
  while (e != nullptr) {
    const Entry* next = e->next_all;
    delete e;
    e = next;
  }
  DeleteTree(root_);
}

void IrradianceCache::DeleteTree(Node* node) {
  for (auto& c : node->children) {
    Node* child = c.load(std::memory_order_relaxed);
    if (child != nullptr) DeleteTree(child);  // recursion depth <= kMaxDepth
  }
  Block* b = node->head.load(std::memory_order_relaxed);
  while (b != nullptr) {
    Block* next = b->next;
    Block::Destroy(b);
    b = next;
  }
  delete node;
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
  static_assert(sizeof(Block) % alignof(Slot) == 0, "slots must be aligned after the header");
  void* memory = ::operator new(sizeof(Block) + capacity * sizeof(Slot));
  Block* b = new (memory) Block;
  b->capacity = capacity;
  b->next = next;
  for (int i = 0; i < capacity; ++i) new (&b->slots()[i]) Slot;
  return b;
}

void IrradianceCache::Block::Destroy(Block* b) {
  for (int i = 0; i < b->capacity; ++i) b->slots()[i].~Slot();
  b->~Block();
  ::operator delete(b);
}

void IrradianceCache::AddToNode(Node* node, const IrradianceRecord& r) {
  Block* head = node->head.load(std::memory_order_acquire);
  for (;;) {
    if (head != nullptr) {
      const int i = head->claimed.fetch_add(1, std::memory_order_relaxed);
      if (i < head->capacity) {
        head->slots()[i].record = r;
        head->slots()[i].ready.store(true, std::memory_order_release);
        return;
      }
    }
    // No block yet, or the newest one is full: push a new one holding r.
    Block* fresh =
        Block::Create(head ? std::min(2 * head->capacity, kMaxBlock) : kFirstBlock, head);
    fresh->slots()[0].record = r;
    fresh->slots()[0].ready.store(true, std::memory_order_relaxed);  // published by the CAS
    fresh->claimed.store(1, std::memory_order_relaxed);
    if (node->head.compare_exchange_strong(head, fresh, std::memory_order_acq_rel,
                                           std::memory_order_acquire)) {
      return;
    }
    // Another thread pushed a block first; `head` now holds it, so try that one.
    Block::Destroy(fresh);
  }
}

IrradianceCache::Node* IrradianceCache::FindOrCreate(const uint32_t cell[3], int depth) {
  Node* node = root_;
  for (int d = 0; d < depth; ++d) {
    const int bit = depth - 1 - d;  // cell is in units of depth `depth`
    const int index =
        ((cell[0] >> bit) & 1) | (((cell[1] >> bit) & 1) << 1) | (((cell[2] >> bit) & 1) << 2);
    std::atomic<Node*>& slot = node->children[index];
    Node* child = slot.load(std::memory_order_acquire);
    if (child == nullptr) {
      Node* fresh = new Node;
      // The loser of a race deletes its node and uses the winner's (acquire makes it readable).
      if (slot.compare_exchange_strong(child, fresh, std::memory_order_acq_rel,
                                       std::memory_order_acquire)) {
        child = fresh;
      } else {
        delete fresh;
      }
    }
    node = child;
  }
  return node;
}

void IrradianceCache::Insert(const IrradianceRecord& r) {
  if (!IsValidRecord(r)) return;

  // The record's validity box, in grid units.
  const double reach = double(max_accuracy_) * double(r.radius) * (1 + kReachSlack);
  double lo[3], hi[3], width = 0;
  bool inside = true;
  for (int k = 0; k < 3; ++k) {
    lo[k] = ToGrid(double(r.position[k]) - reach, k);
    hi[k] = ToGrid(double(r.position[k]) + reach, k);
    inside = inside && lo[k] >= 0 && hi[k] < kGridRes;
    width = std::max(width, hi[k] - lo[k]);
  }

  if (!inside) {
    AddToNode(root_, r);
  } else {
    // Deepest level whose cells (2^shift grid units) are at least as wide as the box. Then on
    // each axis floor(hi) - floor(lo) <= 2^shift, so the box touches at most 2 cells per axis.
    int shift = 0;
    while (shift < kMaxDepth && std::ldexp(1.0, shift) < width) ++shift;
    uint32_t cell_lo[3], cell_hi[3];
    for (int k = 0; k < 3; ++k) {
      cell_lo[k] = uint32_t(lo[k]) >> shift;
      cell_hi[k] = uint32_t(hi[k]) >> shift;
    }
    uint32_t cell[3];
    for (cell[2] = cell_lo[2]; cell[2] <= cell_hi[2]; ++cell[2]) {
      for (cell[1] = cell_lo[1]; cell[1] <= cell_hi[1]; ++cell[1]) {
        for (cell[0] = cell_lo[0]; cell[0] <= cell_hi[0]; ++cell[0]) {
          AddToNode(FindOrCreate(cell, kMaxDepth - shift), r);
        }
      }
    }
  }

  Entry* e = new Entry{r, nullptr};
  const Entry* old = all_.load(std::memory_order_relaxed);
  do {
    e->next_all = old;
  } while (
      !all_.compare_exchange_weak(old, e, std::memory_order_release, std::memory_order_relaxed));
  size_.fetch_add(1, std::memory_order_relaxed);
}

bool IrradianceCache::Lookup(const Vec3& x, const Vec3& n, float a, Vec3* irradiance,
                             LookupInfo* info) const {
  Accumulator acc{x, n, std::min(a, max_accuracy_)};
  const auto scan = [&acc](const Node* node) {
    for (const Block* b = node->head.load(std::memory_order_acquire); b != nullptr; b = b->next) {
      const int filled = std::min(b->claimed.load(std::memory_order_relaxed), b->capacity);
      const Slot* slots = b->slots();
      for (int i = 0; i < filled; ++i) {
        if (slots[i].ready.load(std::memory_order_acquire)) acc.Add(slots[i].record);
      }
    }
  };
  uint32_t cell[3];
  if (!CellOf(x, cell)) {
    // Outside the root cube only records whose box is not inside the root can count, and those
    // are all in the root node.
    scan(root_);
  } else {
    const Node* node = root_;
    for (int d = 0; node != nullptr; ++d) {
      scan(node);
      if (d == kMaxDepth) break;
      const int bit = kMaxDepth - 1 - d;
      const int index =
          ((cell[0] >> bit) & 1) | (((cell[1] >> bit) & 1) << 1) | (((cell[2] >> bit) & 1) << 2);
      node = node->children[index].load(std::memory_order_acquire);
    }
  }
  return acc.Finish(irradiance, info);
}

bool IrradianceCache::LookupBruteForce(const Vec3& x, const Vec3& n, float a, Vec3* irradiance,
                                       LookupInfo* info) const {
  Accumulator acc{x, n, std::min(a, max_accuracy_)};
  ForEach([&acc](const IrradianceRecord& r) { acc.Add(r); });
  return acc.Finish(irradiance, info);
}

}  // namespace irfarm
