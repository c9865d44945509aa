// IrradianceCache: the in-memory irradiance cache of one process, an octree of IrradianceRecord
// shared by all render threads. Inserts and lookups are lock-free: child pointers and per-node
// record lists are atomics updated with compare-and-swap, nothing is moved or freed before the
// cache is destroyed, and a lookup takes no lock and allocates nothing.
//
// Layout (pbrt-v2 style): a record can be reused at x only when |x - x_i| < a * R_i, so with the
// largest accuracy a_max any lookup will use, its "validity box" is the cube of half-size
// a_max * R_i around x_i. The record is stored in every node that overlaps that box, at the
// deepest level whose node edge is still >= the box edge (so at most 2 nodes per axis, <= 8
// nodes), or in the root if the box is not inside the root cube. A lookup at x then only walks
// the single root-to-leaf path containing x. Each record sits at exactly one depth and the path
// has one node per depth, so no record is seen twice by a lookup.
//
// Node geometry is integer: positions are mapped to a 2^20 grid over the root cube with one
// monotone double-precision expression, so "x is in the record's box" implies "x's path visits a
// node holding the record" exactly, with no epsilon, at any scene scale.
//
// Measured cost (100k records on the walls of a unit room, radii 0.01..0.1, one thread of the
// project's 2-vCPU EPYC machines): ~0.8 us per lookup at a = 0.1 (1.1 records used), ~1.5 us at
// a = 0.2 (4.5 used); ~1-2 us per insert; ~0.65-0.8 KB per record, mostly octree nodes and the
// per-node record copies.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>

#include "cache/irradiance_record.h"
#include "cache/math.h"

namespace irfarm {

struct CacheSettings {
  Bounds3 bounds;  // scene bounds, world space; padded and made a cube for the root node
  // Largest accuracy `a` any lookup will use, in (0, 1] (clamped into it). Determines how far a
  // record reaches (a_max * R_i). 0.2 is rpict's default -aa.
  float max_accuracy = 0.2f;
};

struct LookupInfo {
  int records_used = 0;  // records that counted
  float weight_sum = 0;  // sum of their weights w_i
  int remote_records_used = 0;  // of records_used, those with origin != 0 (made elsewhere)
};

class IrradianceCache {
 public:
  explicit IrradianceCache(const CacheSettings& settings);
  ~IrradianceCache();
  IrradianceCache(const IrradianceCache&) = delete;
  IrradianceCache& operator=(const IrradianceCache&) = delete;

  // Adds a copy of r. Thread-safe and lock-free; may run concurrently with lookups. Records that
  // fail IsValidRecord are ignored (records from disk or the wire are validated before this, and
  // records computed by the integrator are valid by construction).
  void Insert(const IrradianceRecord& r);

  // Interpolated irradiance at point x with unit normal n, accuracy a (Ward's rule, see
  // RecordWeight in cache/irradiance_weight.h): E = sum w_i E_i / sum w_i over the records that
  // count. a is clamped to max_accuracy(). Returns false and leaves *irradiance untouched when no
  // record counts. info may be null; when given it is always filled. Thread-safe, allocation-free.
  bool Lookup(const Vec3& x, const Vec3& n, float a, Vec3* irradiance, LookupInfo* info) const;

  // Same rule and result as Lookup (up to summation order) by scanning every record; for tests.
  bool LookupBruteForce(const Vec3& x, const Vec3& n, float a, Vec3* irradiance,
                        LookupInfo* info) const;

  // Number of records inserted (records of inserts still in progress may be missing).
  size_t size() const { return size_.load(std::memory_order_relaxed); }
  float max_accuracy() const { return max_accuracy_; }

  // Calls f(const IrradianceRecord&) once per record, newest first. Safe during inserts: sees
  // every record whose Insert finished before the call started, and maybe some newer ones.
  template <typename F>
  void ForEach(F f) const {
    for (const Entry* e = all_.load(std::memory_order_acquire); e != nullptr; e = e->next_all) {
      f(e->record);
    }
  }

 private:
  static constexpr int kMaxDepth = 20;  // root is depth 0; 2^20 cells per axis at the deepest

  // A node's records are kept in a push-front list of blocks, each an array of record copies, so
  // a lookup reads them sequentially instead of chasing one pointer per record (2-4x faster
  // lookups on 100k records, whose lists do not fit in cache). Blocks double in capacity from
  // kFirstBlock to kMaxBlock, so the many deep nodes holding one or two records waste little.
  // Writers claim a slot with fetch_add on `claimed`, copy the record, then set `ready`
  // (release); readers skip slots that are not ready yet. A full block is replaced by pushing a
  // new one with a CAS on the node's head. `next`, `capacity` and `slots` are written before the
  // block is published and never change.
  struct Slot {
    std::atomic<bool> ready{false};
    IrradianceRecord record;
  };
  // Header immediately followed by `capacity` slots, in one allocation (Create / Destroy), so a
  // lookup's first touch of a block already brings in its first records.
  struct Block {
    static Block* Create(int capacity, Block* next);
    static void Destroy(Block* b);
    Slot* slots() { return reinterpret_cast<Slot*>(this + 1); }
    const Slot* slots() const { return reinterpret_cast<const Slot*>(this + 1); }

    std::atomic<int> claimed{0};  // slots handed out; may run past capacity when full
    int capacity = 0;
    Block* next = nullptr;
  };
  static constexpr int kFirstBlock = 1, kMaxBlock = 64;

  struct Node {
    Node();
    std::atomic<Block*> head;        // newest block of this node's records
    std::atomic<Node*> children[8];  // index bit 0: x, bit 1: y, bit 2: z (1 = upper half)
  };
  // Each record once, for ForEach, LookupBruteForce and size accounting.
  struct Entry {
    IrradianceRecord record;
    const Entry* next_all;
  };
  struct Accumulator;

  // Grid coordinate (0 at the root's low face, 2^kMaxDepth at the high face) of coordinate v on
  // axis k. Monotone in v, which is all the octree's correctness needs.
  double ToGrid(double v, int k) const { return (v - root_lo_[k]) * grid_scale_; }
  // Cell of x at the deepest level; false if x is outside the root cube (or not finite).
  bool CellOf(const Vec3& x, uint32_t cell[3]) const;
  Node* FindOrCreate(const uint32_t cell[3], int depth);
  static void AddToNode(Node* node, const IrradianceRecord& r);
  static void DeleteTree(Node* node);

  float max_accuracy_;
  double root_lo_[3];
  double grid_scale_;  // grid cells per scene unit at depth kMaxDepth
  Node* root_;
  std::atomic<const Entry*> all_{nullptr};  // every record, push-front, for ForEach and cleanup
  std::atomic<size_t> size_{0};
};

}  // namespace irfarm
