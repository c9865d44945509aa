// IrradianceCache: the in-memory irradiance cache of one process, an octree of irradiance records
// shared by all render threads. Inserts and lookups are lock-free: child pointers, per-node record
// blocks and per-node radius bounds are atomics updated with compare-and-swap or fetch_add,
// nothing is moved or freed before the cache is destroyed, and a lookup takes no lock and
// allocates nothing.
//
// Layout (a loose octree, as RADIANCE's ambient tree): each record is stored ONCE, in the node
// whose cell contains its position x_i at the deepest level whose cell edge is still at least
// kCellPerReach times its largest reach a_max * R_i (or in the root if x_i is outside the root
// cube), or in a leaf above that level until that leaf has held kSplitAfter such records. Every
// node also keeps, per child, the largest R_i stored in that child's subtree. A record can count at
// x only when |x - x_i| < a * R_i, so a lookup at accuracy a only descends into children whose
// cell, grown by a * (that largest R_i) on every side, contains x: it visits few nodes (those whose
// records can reach x at the accuracy actually asked for, not at a_max) and no record twice.
//
// Records sit in per-node blocks split into a hot array (position and R, 16 bytes: all a lookup
// reads to reject a candidate by squared distance) and a cold array (normal, irradiance, origin
// and the completion-order link), so a lookup streams through 4 candidates per cache line and
// touches a cold entry only for the few records within reach.
//
// Node geometry is integer: positions are mapped to a 2^20 grid over the root cube with one
// monotone double-precision expression, and the grown-cell test uses the same mapping with a
// relative slack far above float rounding, so "x is within a * R_i of x_i" implies "the lookup
// visits the node holding the record" exactly, with no absolute epsilon, at any scene scale.
//
// Records are further split by the signed dominant axis of their normal (six octrees per level,
// see kClasses): a lookup walks only the classes its normal can reach under Ward's rule. Measured
// on living-room (furniture, plants; 700 record rays, seed 7, 2 threads, in one run): records
// scanned per lookup 510 -> 168, records within reach 33 -> 11, render-phase CPU 34.3 -> 27.6 s,
// total CPU 49.0 -> 42.3 s, relMSE unchanged (0.0258 / 0.0255); bench_micro (walls of a box,
// one class per wall) unchanged.
//
// Measured (one thread, records on the walls of a room as in bench/micro_bench.cc, lookups at
// a = a_max / 2, thread CPU time on the shared 2-vCPU machine): 0.5-0.8 / 0.8-0.9 / 0.9-1.1 us
// per lookup at 1k / 10k / 100k records, 1.5-2.5x faster than the previous layout (every record
// copied into up to 8 nodes) in the same run; 64 bytes per record (56 before neighbour
// clamping added its radius), octree overhead 0.55-0.75x
// the records' bytes (tests/cache: RecordsAreCompactAndTheOctreeSmall). What remains is about
// 10 node visits, ~130 candidates and ~6 full weighings per lookup at 100k records, mostly cache
// misses and data-dependent branches. The renderer's lookups go through LookupNear (a pixel's
// samples share one gathered region of ~16 candidates, weighed 4 at a time): 150-215 ns per
// lookup in bench_micro's pixel runs at 1k-100k records.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>

#include "cache/irradiance_record.h"
#include "cache/occluder_plane.h"
#include "core/math.h"

namespace irfarm {

struct CacheSettings {
  Bounds3 bounds;  // scene bounds, world space; padded and made a cube for the root node
  // Largest accuracy `a` any lookup will use, in (0, 1] (clamped into it). Determines how far a
  // record reaches (a_max * R_i). 0.2 is rpict's default -aa.
  float max_accuracy = 0.2f;
  // Neighbour clamping (Krivanek et al. 2006, as Mitsuba 0.5's irrcache does, gentler): a
  // record's radius is kept within R_j + slope * |x_i - x_j| of every record j of its level, both
  // for the record inserted and for the records it is inserted among, so that a record next to a
  // small one (in a gap, a corner) cannot reach over it into light it never saw. 0 = off.
  float neighbour_slope = 0;
  // Lookups return the value at x of the plane fitted to the records that count by weighted least
  // squares (Ward's weights; cache/local_linear_fit.h) instead of their weighted mean, where the
  // records span the tangent plane. false: Ward's weighted mean.
  bool linear_fit = false;
};

struct LookupInfo {
  int records_used = 0;         // records that counted
  float weight_sum = 0;         // sum of their weights w_i
  float weight_sq_sum = 0;      // sum of w_i^2: sum w_i^2 / (sum w_i)^2 is the share of one
                                // record's variance that the weighted mean keeps
  int remote_records_used = 0;  // of records_used, those with origin != 0 (made elsewhere)
  // Given a narrow accuracy (the lookups' `narrow_a`): whether some record counts under the rule
  // at that smaller accuracy too (RecordWeight(x, n, narrow_a, r) > 0 for one of them).
  bool counts_at_narrow = false;
  Vec3 narrow_irradiance;    // ... and their interpolated irradiance (when counts_at_narrow)
  bool from_region = false;  // LookupNear: answered from the region's records, no walk
};

// The records that may count at any point within `radius` of `center` with a normal within
// `angle` of `normal` (at accuracy a, levels <= max_level): the camera samples of one pixel land on
// the same surface close together, and a lookup among these few candidates gives the same answer
// as a walk of the octree (IrradianceCache::LookupNear). Plain data, no allocation: one per
// render thread (or pixel), kept across its lookups.
struct LookupRegion {
  static constexpr int kMaxRecords = 48;
  Vec3 center, normal;
  float radius = 0, cos_angle = 2;  // cos_angle 2: covers nothing (empty region)
  float a = 0;
  int max_level = 0;
  const void* cache = nullptr;  // the cache gathered from (refs point into it)
  size_t generation = 0;        // its insert count when gathered
  int count = -1;  // records in refs; -1 = more than kMaxRecords (lookups walk the octree)
  uint64_t refs[kMaxRecords];
  // Copies of the candidates' positions and radii (neighbour-clamped, as gathered: the region is
  // gathered again after any insert, and an insert lowers its neighbours' radii before it counts),
  // so that a lookup rejects the candidates beyond reach 4 at a time without touching the records.
  alignas(16) float x[kMaxRecords], y[kMaxRecords], z[kMaxRecords], r[kMaxRecords];
  // The rest of what the rule reads (IrradianceCache::RegionWeights4), as structure of arrays so
  // that a lookup weighs 4 candidates at a time without touching the records: normal n, the
  // occluder o (unpacked) and |o|^2, irradiance E, and whether another process made the record.
  // Measured in bench_micro's pixel runs at 100k records, rebuilding each record from its block
  // (occluder unpacked) and weighing it alone took half of a lookup's time, and reading the
  // clamped radius from the record a quarter.
  alignas(16) float nx[kMaxRecords], ny[kMaxRecords], nz[kMaxRecords];
  alignas(16) float ox[kMaxRecords], oy[kMaxRecords], oz[kMaxRecords], o2[kMaxRecords];
  float ex[kMaxRecords], ey[kMaxRecords], ez[kMaxRecords];
  bool remote[kMaxRecords];
};

// Bytes held by a cache (IrradianceCache::MemoryUse). record_bytes counts the filled record
// slots (hot and cold parts); octree_bytes everything else: nodes, block headers and the unused
// slots of partly filled blocks.
struct CacheMemory {
  size_t records = 0;
  size_t bytes_per_record = 0;  // in memory, hot + cold part
  size_t record_bytes = 0;
  size_t octree_bytes = 0;
  size_t nodes = 0;
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
  // count, or with CacheSettings::linear_fit the weighted least-squares plane's value at x. a is
  // clamped to max_accuracy(). Returns false and leaves *irradiance untouched when no record
  // counts. info may be null; when given it is always filled. Thread-safe, allocation-free. Only
  // records with level <= max_level count. With 0 < narrow_a < a, info->counts_at_narrow also tells
  // whether any record counts at narrow_a (the renderer weighs records at a and makes a new one
  // where none counts at narrow_a).
  bool Lookup(const Vec3& x, const Vec3& n, float a, Vec3* irradiance, LookupInfo* info,
              int max_level = kAnyLevel, float narrow_a = 0) const;

  // Same rule and result as Lookup (up to summation order), for a run of lookups close together
  // (the samples of a pixel). When `region` covers (x, n) at (a, max_level) and nothing was
  // inserted since it was gathered, only its records are weighed (info->from_region); otherwise
  // it is first gathered anew around (x, n) with `radius` and `angle` (radians). Regions with too
  // many candidates are not kept: lookups they cover walk the octree. Allocation-free.
  bool LookupNear(const Vec3& x, const Vec3& n, float a, float radius, float angle,
                  LookupRegion* region, Vec3* irradiance, LookupInfo* info,
                  int max_level = kAnyLevel, float narrow_a = 0) const;

  // Same rule and result as Lookup (up to summation order) by scanning every record; for tests.
  bool LookupBruteForce(const Vec3& x, const Vec3& n, float a, Vec3* irradiance, LookupInfo* info,
                        int max_level = kAnyLevel, float narrow_a = 0) const;
  static constexpr int kAnyLevel = 255;

  // Number of records inserted (records of inserts still in progress may be missing).
  size_t size() const { return size_.load(std::memory_order_relaxed); }
  float max_accuracy() const { return max_accuracy_; }
  // The largest accuracy a cache made with CacheSettings.max_accuracy = a looks up with: a
  // clamped to 1; NaN or a <= 0 become 0 (records then reach nowhere, no lookup succeeds).
  static float ClampedMaxAccuracy(float a) { return a > 0 ? std::min(a, 1.0f) : 0.0f; }

  // Memory held now, by walking the tree (O(nodes); for tests and statistics, not hot paths).
  CacheMemory MemoryUse() const;

  // Calls f(const IrradianceRecord&) once per record, in reverse order of completed inserts
  // (newest first). Safe during inserts: sees every record whose Insert finished before the call
  // started, and maybe some newer ones, always as a prefix of the newest-first order.
  template <typename F>
  void ForEach(F f) const {
    ForEachNewer(0, f);
  }
  // ForEach over the records newer than `mark` only, where `mark` is what an earlier call
  // returned (0: every record); returns the mark of the newest record it saw. New records are
  // only ever put in front of the newest-first order, so calls chained through their marks see
  // each record once, at a cost in the new records alone (a worker publishing its new records
  // every 50 ms walked all of its cache each time: 0.7 ms at 40k records, 63 ms at 400k,
  // bench_micro BM_NewRecordsWalk).
  template <typename F>
  uint64_t ForEachNewer(uint64_t mark, F f) const {
    const uint64_t head = all_.load(std::memory_order_acquire);
    for (uint64_t ref = head; ref != 0 && ref != mark;) {
      const Block* b = BlockOf(ref);
      const int i = SlotOf(ref);
      f(b->Record(i));
      ref = b->cold()[i].next_all;
    }
    return head;
  }

 private:
  static constexpr int kMaxDepth = 20;  // root is depth 0; 2^20 cells per axis at the deepest

  // The rest of a record, read only for candidates within reach. next_all links records in
  // completion order (a RecordRef, 0 = end) for ForEach.
  struct Cold {
    Vec3 normal;
    Vec3 irradiance;
    uint32_t origin;
    // Neighbour clamping's radius, <= the hot part's R (which stays the octree's and the distance
    // pre-test's upper bound); lowered by later inserts while lookups read it.
    std::atomic<float> clamped{INFINITY};
    uint64_t next_all;
    uint8_t level;
    PackedOccluder occluder;  // in what was padding at the end
  };
  static_assert(sizeof(Cold) == 48, "a record is at most 64 bytes with its 16 hot ones");
  // Bytes of one record in memory: 4 hot floats (x, y, z, R) and its Cold part.
  static constexpr size_t kRecordBytes = 4 * sizeof(float) + sizeof(Cold);

  // A node's records are kept in a push-front list of blocks. A block is one kBlockAlign-aligned
  // allocation: this header, then the hot part as structure of arrays (x[capacity], y[], z[],
  // radius[]: all a lookup reads to reject a candidate by squared distance, 4 candidates per SSE
  // step), then capacity Cold entries. Blocks double in capacity from kFirstBlock to
  // kMaxBlock, so the many nodes holding a few records waste little and full nodes are read in long
  // sequential runs. A writer claims a slot with fetch_add on `claimed`, writes it, then sets its
  // bit in `ready` (release); readers load `ready` (acquire) once per block and read only ready
  // slots. A full block is replaced by pushing a new one with a CAS on the node's head. `next`
  // and `capacity` are written before the block is published and never change.
  struct Block {
    static Block* Create(int capacity, Block* next);
    static void Destroy(Block* b);
    static size_t Bytes(int capacity) { return sizeof(Block) + capacity * kRecordBytes; }
    float* hot() { return reinterpret_cast<float*>(this + 1); }
    const float* hot() const { return reinterpret_cast<const float*>(this + 1); }
    float* x() { return hot(); }
    float* y() { return hot() + capacity; }
    float* z() { return hot() + 2 * capacity; }
    float* radius() { return hot() + 3 * capacity; }
    const float* x() const { return hot(); }
    const float* y() const { return hot() + capacity; }
    const float* z() const { return hot() + 2 * capacity; }
    const float* radius() const { return hot() + 3 * capacity; }
    Cold* cold() { return reinterpret_cast<Cold*>(hot() + 4 * capacity); }
    const Cold* cold() const { return reinterpret_cast<const Cold*>(hot() + 4 * capacity); }
    IrradianceRecord Record(int i) const;  // slot i, which must be ready

    std::atomic<uint64_t> ready{0};  // bit i: slot i is written
    std::atomic<int> claimed{0};     // slots handed out; may run past capacity when full
    int capacity = 0;                // multiple of 4 (whole SSE steps)
    Block* next = nullptr;
  };
  static constexpr int kFirstBlock = 4, kMaxBlock = 64;
  static constexpr size_t kBlockAlign = 64;  // see RecordRef

  // A RecordRef packs (Block*, slot) into 64 bits: blocks are 64-byte aligned and kMaxBlock <= 64,
  // so the slot fits in the pointer's low 6 bits.
  static uint64_t RefOf(const Block* b, int slot) {
    return reinterpret_cast<uintptr_t>(b) | uint64_t(slot);
  }
  static const Block* BlockOf(uint64_t ref) { return reinterpret_cast<const Block*>(ref & ~63ull); }
  static int SlotOf(uint64_t ref) { return int(ref & 63); }

  // 56 bytes: everything a lookup needs to decide which children to enter is in the parent.
  struct Node {
    std::atomic<int> deeper{0};  // records stored here that belong deeper (while a leaf)
    std::atomic<float> child_radius[8] = {};  // largest R_i in child i's subtree; 0 = none yet
    std::atomic<Block*> head{nullptr};        // newest block of this node's own records
    std::atomic<Node*> children{nullptr};     // 8 nodes allocated together, index bit 0: x,
                                              // bit 1: y, bit 2: z (1 = upper half)
  };
  struct Accumulator;

  // Grid coordinate (0 at the root's low face, 2^kMaxDepth at the high face) of coordinate v on
  // axis k. Monotone in v, which is all the octree's correctness needs.
  double ToGrid(double v, int k) const { return (v - root_lo_[k]) * grid_scale_; }
  // Cell of x at the deepest level; false if x is outside the root cube (or not finite).
  bool CellOf(const Vec3& x, uint32_t cell[3]) const;
  static void AddToNode(Node* node, const IrradianceRecord& r, std::atomic<uint64_t>* all);
  void InsertUnclamped(const IrradianceRecord& r);
  // Lowers the clamped radius of the published copies of r (its position and radius) to bound.
  void LowerOwn(const IrradianceRecord& r, float bound) const;
  // Calls f(block, slot) for every ready record j of the blocks from `head` with
  // |p - x_j| < alpha * R_j + beta (where that is positive), tested 4 at a time.
  template <typename F>
  static void ForEachWithin(const Block* head, const Vec3& p, float alpha, float beta, F&& f);
  // Calls f(block, slot) for every ready record j of tree `tree` (every class) closer to x than
  // alpha * R_j + beta (alpha >= 0; records where that is not positive are skipped).
  template <typename F>
  void ForEachNeighbour(int tree, const Vec3& x, float alpha, float beta, F f) const;
  // Neighbour clamping of r's radius against its neighbours, then of theirs against r's.
  float ClampToNeighbours(const IrradianceRecord& r) const;
  void LowerNeighbours(const IrradianceRecord& r) const;
  static void GrowRadius(std::atomic<float>* max_radius, float radius);
  static void DeleteTree(Node* node);
  static void AddMemory(const Node* node, CacheMemory* m);

  // One octree per cache level (records of level >= kTrees - 1 share the last): a lookup at
  // level l walks trees 0..l only, so the few wide secondary records never cost camera lookups.
  static constexpr int kTrees = 2;
  static int TreeOf(int level) { return level < kTrees ? level : kTrees - 1; }
  // Each tree is split by the records' normals into kClasses octrees, one per signed dominant
  // axis (+x, -x, +y, -y, +z, -z: the faces of a cube map). A record counts only where
  // sqrt(1 - n . n_i) < a, i.e. within the angle acos(1 - a^2) of the lookup's normal (16 degrees
  // at a = 0.2), so a lookup walks only the classes that reach that close to n: one on walls and
  // floors, two or three near a cube edge or corner. Where normals vary (furniture, foliage, both
  // sides of thin surfaces) most records within reach of x face elsewhere; measured on
  // living-room at main's defaults, 30 of the 35 records within reach of a secondary lookup failed
  // Ward's rule on the normal term alone, after being scanned and weighed.
  static constexpr int kClasses = 6;
  static int ClassOf(const Vec3& n);
  // Bit c set: class c may hold a record that counts at normal n with accuracy a (conservative:
  // a necessary condition, so a class may be walked in vain but never skipped wrongly).
  static unsigned ClassesNear(const Vec3& n, float a);
  // Bit c set: class c may hold a normal within `angle` (radians) of n.
  static unsigned ClassesWithin(const Vec3& n, float angle);
  static unsigned ClassesWithinSin(const Vec3& n, float margin);
  // Calls visit(head) for the record-block list of every node of trees 0..TreeOf(max_level),
  // classes `classes`, whose records may lie within reach_scale * R_i + extra grid units of x.
  template <typename F>
  void WalkNodes(const Vec3& x, unsigned classes, int max_level, float reach_scale, float extra,
                 F visit) const;
  void Gather(const Vec3& x, const Vec3& n, float a, float radius, float angle, int max_level,
              LookupRegion* region) const;
  // RecordWeight of region candidates k0..k0 + 3 at (x, n, a), in the same float operations lane
  // by lane: the same weights as the scalar rule.
  static void RegionWeights4(const LookupRegion& region, int k0, const Vec3& x, const Vec3& n,
                             float a, float w[4]);

  float max_accuracy_;
  float neighbour_slope_;
  bool linear_fit_;
  double root_lo_[3];
  double grid_scale_;  // grid cells per scene unit at depth kMaxDepth
  Node* roots_[kTrees][kClasses];
  std::atomic<uint64_t> all_{0};  // newest completed record (a RecordRef), for ForEach
  std::atomic<size_t> size_{0};
  std::atomic<uint64_t> inserts_published_{0};  // Insert's ordering point (see there)
};

}  // namespace irfarm
