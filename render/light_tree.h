// A light tree over the triangles of one emissive mesh: picks a triangle in proportion to an
// estimate of what it sends to a shading point, instead of by area.
//
// Each node bounds its triangles' positions (a box), their emitting directions (a cone of
// normals) and their power (radiance luminance x area). Its importance at a point p with facing
// normal n is power x cos(theta') x cos(theta_i') / d^2, where theta' is the smallest angle any
// of its triangles' normals can make with a direction from the box towards p, theta_i' the
// smallest angle a direction from p into the box can make with n, and d the distance to the
// box's centre (not less than the box's half diagonal) (Conty Estevez and Kulla 2018, "Importance
// sampling of many lights with adaptive tree splitting"; pbrt-v4's BVH light sampler). The bounds
// are conservative: a node whose importance is 0 holds no triangle that can light p (all emit
// away from p, or all lie below p's horizon), so picking stays unbiased. A leaf (one triangle)
// also tests p against the triangle's plane and its three corners against p's horizon exactly.
//
// Sample() walks from the root, choosing among a node's grandchildren (up to four: the binary
// tree's levels are walked two at a time, see WideNode) in proportion to their importances, which
// one Float4 pass computes side by side; Pmf() walks the same way to a given triangle (the child
// whose range of leaves holds it) and multiplies the same probabilities, so that the two agree
// exactly (MIS). Both allocate nothing.
//
// The tree is built by splitting at the bucket boundary with the lowest surface-area-orientation
// cost (box area x orientation measure x power, Conty Estevez and Kulla), along each axis. A range
// of at most kBucketTriangles triangles whose normals lie within a narrow cone becomes one leaf
// (a bucket) instead of a subtree: the walk stops there and picks one of its triangles that faces
// p, by power. A lamp tessellated into hundreds of triangles (a tube, a disk) is three levels
// shallower that way, and each level costs two importances per sample.
#pragma once

#include <cstdint>
#include <vector>

#include "core/float4.h"
#include "core/math.h"
#include "render/light_triangle.h"

namespace irfarm {

class LightTree {
 public:
  // Builds the tree over `triangles` (indices into it are what Sample returns), each with power
  // `luminance` x its area. Triangles of zero area are left out (they emit nothing).
  void Build(const std::vector<LightTriangle>& triangles, float luminance);

  bool empty() const { return nodes_.empty(); }
  // The root's importance at (p, n): 0 exactly when no triangle can light p. n may be zero (a
  // point that takes light from all directions: no horizon test).
  float Importance(const Vec3& p, const Vec3& n) const;
  // Picks a triangle with probability *pmf, or returns -1 (no triangle reached; always when
  // Importance(p, n) is 0, which the caller tests first). `stop_far`: the walk stops at nodes far
  // from p whose normals lie in a narrow cone and picks among their triangles by power (cheaper;
  // `path`'s camera paths use it, irrcache's direct light does not: its noise is the image's).
  // `u_rest` (optional) receives what is left of u after the pick: uniform in [0, 1) given the
  // pick, and stratified where u was (the walk's rescaling of u within each choice).
  int Sample(const Vec3& p, const Vec3& n, float u, float* pmf, bool stop_far = false,
             float* u_rest = nullptr) const;
  // The probability that Sample(p, n, ..., stop_far) picks triangle `index`.
  float Pmf(const Vec3& p, const Vec3& n, unsigned index, bool stop_far = false) const;

  int depth() const { return depth_; }
  // Leaves holding several triangles (see kBucketTriangles).
  static constexpr int kBucketTriangles = 8;
  size_t node_count() const { return nodes_.size(); }

 private:
  struct Node {
    // Bounds of the triangles' positions: centre, half extents and squared half diagonal.
    Vec3 centre, half;
    float r2 = 0, radius = 0;
    // Cone of emitting normals: axis, cosine and sine of its half-angle, and `spread`, how far
    // a point of the box can lie beyond the centre along such a normal (see NodeImportance).
    Vec3 axis;
    float cos_cone = 1, sin_cone = 0, spread = 0;
    float power = 0;           // luminance x area, summed
    int second = -1;           // interior: index of the second child (the first is the next node)
    int triangle = -1;         // leaf of one triangle: the triangle
    int bucket = -1;           // leaf of several: the first of its `count` entries in buckets_
    int first = 0, count = 0;  // its triangles: order_[first, first + count)
    // Leaf: the triangle's corners and plane, for the exact tests.
    Vec3 p0, p1, p2, ng;
  };
  void SetBounds(Node* node, const Vec3& lo, const Vec3& hi, const Vec3& axis, float cos_cone,
                 float power) const;
  struct Prim;  // a triangle during the build

  int BuildRange(std::vector<Prim>& prims, size_t begin, size_t end, int depth);
  float NodeImportance(const Node& node, const Vec3& p, const Vec3& n) const;

  // The walk's tree. An interior node of the binary tree stands with its grandchildren (its
  // children where those are leaves): up to four lanes, whose bounds are stored lane by lane so
  // that one Float4 pass gives all four importances (NodeImportance's, side by side). Choosing
  // among them in one step halves the walk's depth; measured on make_room 905's tube and disk
  // lamps (perf), the binary walk's two scalar importances per level were a third of the CPU.
  struct WideNode {
    // Per lane: NodeImportance's bounds (Node's fields of the same names).
    float cx[4], cy[4], cz[4], hx[4], hy[4], hz[4], r2[4], radius[4];
    float ax[4], ay[4], az[4], cos_cone[4], sin_cone[4], spread[4], power[4];
    int child[4];    // >= 0: the wide node below; < 0: -1 - the binary leaf (a triangle, a bucket)
    int node[4];     // the binary node each lane stands for (its range of leaves)
    int binary = 0;  // the binary node this one stands for
    int count = 0;   // lanes in use
    unsigned triangle_lanes = 0;  // bit k: lane k is a one-triangle leaf (exact tests too)
  };
  int BuildWide(int binary);
  // The importances of the node's lanes at (p, n) (0 past its count).
  void LaneImportances(const WideNode& w, const Vec3& p, const Vec3& n, float out[4]) const;
  // The exact tests of one-triangle leaf `node` (NodeImportance's first lines): false when the
  // triangle cannot light p.
  bool TriangleCanLight(const Node& node, const Vec3& p, const Vec3& n) const;

  // A bucket leaf's triangle: what the pick within the bucket reads (a point in its plane, its
  // normal, its power) and its index.
  struct BucketEntry {
    Vec3 p0, ng;
    float power = 0;
    int triangle = -1;
  };
  bool IsLeaf(const Node& node) const { return node.triangle >= 0 || node.bucket >= 0; }
  // Whether a walk with stop_far stops at interior node `node` (see kStopCosCone).
  bool StopsAt(const Node& node, const Vec3& p) const;
  // The last k in [0, count) with cum[k] <= target (cum[0] <= target, cum nondecreasing), for
  // target = cum[0] + u (cum[count] - cum[0]).
  static int LastAtOrBelow(const double* cum, int count, float u, double target);
  // The probability of triangle `triangle` when node's triangles are picked by power.
  float RangeProbability(const Node& node, int triangle) const;
  // Picks a triangle of bucket leaf `node` among those p lies in front of, by power: returns the
  // entry and its probability, or -1 when p is behind them all. With `wanted` >= 0, the
  // probability of that triangle instead (0 when it is not picked from p).
  int PickInBucket(const Node& node, const Vec3& p, float u, int wanted, float* prob,
                   float* u_rest = nullptr) const;

  std::vector<Node> nodes_;
  std::vector<WideNode> wide_;  // wide_[0] stands for nodes_[0] (when that is not a leaf)
  std::vector<BucketEntry> buckets_;
  std::vector<int> order_;       // the triangles in the order of the tree's leaves
  std::vector<double> cum_;      // cum_[k]: the power of order_[0, k)
  std::vector<float> power_of_;  // per triangle
  std::vector<int> position_;    // per triangle: its index in order_
  std::vector<int> leaf_;        // per triangle: its leaf node, -1 when left out
  int depth_ = 0;
};

}  // namespace irfarm
