#include "render/light_tree.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace irfarm {
namespace {

// A cone of directions: a unit axis and the cosine of its half-angle (-1: every direction).
struct Cone {
  Vec3 axis;
  float cos_half = 1;
  bool empty = true;
};

// Angle between unit vectors, accurate for nearly equal and nearly opposite ones.
float AngleBetween(const Vec3& a, const Vec3& b) {
  const float d = Dot(a, b);
  if (d < 0) return kPi - 2 * std::asin(std::min(1.0f, Length(a + b) * 0.5f));
  return 2 * std::asin(std::min(1.0f, Length(a - b) * 0.5f));
}

// The smallest cone holding both (Conty Estevez and Kulla's merge), widened by a hair so that
// rounding never leaves a normal outside it.
Cone Union(const Cone& a, const Cone& b) {
  if (a.empty) return b;
  if (b.empty) return a;
  constexpr float kMargin = 1e-4f;
  const float ta = std::acos(std::clamp(a.cos_half, -1.0f, 1.0f));
  const float tb = std::acos(std::clamp(b.cos_half, -1.0f, 1.0f));
  const float td = AngleBetween(a.axis, b.axis);
  if (std::min(td + tb, kPi) <= ta) return a;
  if (std::min(td + ta, kPi) <= tb) return b;
  const float to = 0.5f * (ta + td + tb) + kMargin;
  Cone c;
  c.empty = false;
  const Vec3 k = Cross(a.axis, b.axis);
  if (to >= kPi || LengthSquared(k) < 1e-12f) {  // every direction (or opposite axes)
    c.axis = a.axis;
    c.cos_half = -1;
    return c;
  }
  // Rotate a's axis towards b's by to - ta (about k, which is perpendicular to it).
  const float tr = to - kMargin - ta;
  const Vec3 kn = Normalize(k);
  c.axis = Normalize(a.axis * std::cos(tr) + Cross(kn, a.axis) * std::sin(tr));
  c.cos_half = std::cos(to);
  return c;
}

// Measure of the directions a cone of normals emits into (one-sided emitters: each normal's
// hemisphere, cosine-weighted): 2 pi (1 - cos t) + pi/2 (2 w sin t - cos(t - 2w) - 2 t sin t +
// cos t), w = min(t + pi/2, pi). pi for a single direction.
float OrientationMeasure(const Cone& c) {
  const float t = std::acos(std::clamp(c.cos_half, -1.0f, 1.0f));
  const float w = std::min(t + 0.5f * kPi, kPi);
  const float s = std::sin(t);
  return 2 * kPi * (1 - std::cos(t)) +
         0.5f * kPi * (2 * w * s - std::cos(t - 2 * w) - 2 * t * s + std::cos(t));
}

float BoxArea(const Vec3& lo, const Vec3& hi) {
  const Vec3 e = Max(hi - lo, Vec3());
  return 2 * (e.x * e.y + e.y * e.z + e.z * e.x);
}

// cos(max(0, a - b)) from the cosines and sines of a and b.
float CosMinusClamped(float cos_a, float sin_a, float cos_b, float sin_b) {
  return cos_a >= cos_b ? 1.0f : cos_a * cos_b + sin_a * sin_b;
}
// sin(max(0, a - b)).
float SinMinusClamped(float cos_a, float sin_a, float cos_b, float sin_b) {
  return cos_a >= cos_b ? 0.0f : sin_a * cos_b - cos_a * sin_b;
}

float SafeSqrt(float x) { return std::sqrt(std::max(0.0f, x)); }

// The split search's buckets along one axis: kBuckets equal slices of the centroids' span from lo.
constexpr int kBuckets = 12;
int BucketOf(float centroid, float lo, float span) {
  return std::min(kBuckets - 1, int(kBuckets * (centroid - lo) / span));
}

// A bucket leaf's triangles have normals within this cone (cosine of its half-angle, ~26 degrees):
// picked by power among those facing p, they are within a few times of what the walk below would
// have given them.
constexpr float kBucketCosCone = 0.9f;
// With `stop_far` (Sample, Pmf), the walk stops at an interior node whose normals lie within this
// cone (as a bucket's) and whose bounding sphere's radius is under kStopRadius times p's distance
// to its centre: the node's triangles are then picked by power, with one search of the leaves'
// cumulative powers instead of two node importances per level below.
constexpr float kStopCosCone = 0.9f;
constexpr float kStopRadius = 0.5f;

}  // namespace

struct LightTree::Prim {
  int index = 0;
  Vec3 lo, hi, centroid;
  Cone cone;
  float power = 0;
  Vec3 p0, p1, p2;
};

void LightTree::Build(const std::vector<LightTriangle>& triangles, float luminance) {
  nodes_.clear();
  buckets_.clear();
  wide_.clear();
  leaf_.assign(triangles.size(), -1);
  depth_ = 0;
  std::vector<Prim> prims;
  prims.reserve(triangles.size());
  for (size_t i = 0; i < triangles.size(); ++i) {
    const LightTriangle& t = triangles[i];
    const float power = luminance * t.area;
    if (!(t.area > 0) || !(power > 0) || !std::isfinite(power)) continue;
    Prim p;
    p.index = int(i);
    p.lo = Min(t.p0, Min(t.p1, t.p2));
    p.hi = Max(t.p0, Max(t.p1, t.p2));
    p.centroid = (t.p0 + t.p1 + t.p2) / 3.0f;
    p.cone.axis = t.ng;
    p.cone.cos_half = 1;
    p.cone.empty = false;
    p.power = power;
    p.p0 = t.p0;
    p.p1 = t.p1;
    p.p2 = t.p2;
    prims.push_back(p);
  }
  if (prims.empty()) return;
  nodes_.reserve(2 * prims.size());
  BuildRange(prims, 0, prims.size(), 0);
  // BuildRange leaves each node's triangles contiguous in prims, in the order of the leaves.
  power_of_.assign(triangles.size(), 0.0f);
  order_.clear();
  cum_.assign(1, 0.0);
  position_.assign(triangles.size(), -1);
  for (const Prim& p : prims) {
    position_[size_t(p.index)] = int(order_.size());
    order_.push_back(p.index);
    cum_.push_back(cum_.back() + double(p.power));
    power_of_[size_t(p.index)] = p.power;
  }
  if (!IsLeaf(nodes_[0])) BuildWide(0);
}

int LightTree::BuildWide(int binary) {
  const Node& b = nodes_[size_t(binary)];
  int lanes[4], count = 0;
  for (const int c : {binary + 1, b.second}) {
    const Node& child = nodes_[size_t(c)];
    if (IsLeaf(child)) {
      lanes[count++] = c;
    } else {
      lanes[count++] = c + 1;
      lanes[count++] = child.second;
    }
  }
  const int me = int(wide_.size());
  wide_.emplace_back();
  WideNode w;
  w.binary = binary;
  w.count = count;
  for (int k = 0; k < 4; ++k) {
    // Unused lanes: no power, and bounds that keep their arithmetic finite.
    const Node& l = nodes_[size_t(lanes[std::min(k, count - 1)])];
    const bool used = k < count;
    w.cx[k] = l.centre.x;
    w.cy[k] = l.centre.y;
    w.cz[k] = l.centre.z;
    w.hx[k] = l.half.x;
    w.hy[k] = l.half.y;
    w.hz[k] = l.half.z;
    w.r2[k] = l.r2;
    w.radius[k] = l.radius;
    w.ax[k] = l.axis.x;
    w.ay[k] = l.axis.y;
    w.az[k] = l.axis.z;
    w.cos_cone[k] = l.cos_cone;
    w.sin_cone[k] = l.sin_cone;
    w.spread[k] = l.spread;
    w.power[k] = used ? l.power : 0.0f;
    w.node[k] = used ? lanes[k] : -1;
    w.child[k] = -1;
    if (used && l.triangle >= 0) w.triangle_lanes |= 1u << k;
  }
  for (int k = 0; k < count; ++k)
    w.child[k] = IsLeaf(nodes_[size_t(lanes[k])]) ? -1 - lanes[k] : BuildWide(lanes[k]);
  wide_[size_t(me)] = w;
  return me;
}

bool LightTree::StopsAt(const Node& node, const Vec3& p) const {
  return node.cos_cone >= kStopCosCone &&
         node.r2 < kStopRadius * kStopRadius * LengthSquared(p - node.centre);
}

float LightTree::RangeProbability(const Node& node, int triangle) const {
  const double total = cum_[size_t(node.first + node.count)] - cum_[size_t(node.first)];
  return total > 0 ? float(double(power_of_[size_t(triangle)]) / total) : 0.0f;
}

int LightTree::BuildRange(std::vector<Prim>& prims, size_t begin, size_t end, int depth) {
  depth_ = std::max(depth_, depth);
  const int me = int(nodes_.size());
  nodes_.push_back(Node{});
  nodes_.back().first = int(begin);
  nodes_.back().count = int(end - begin);
  if (end - begin == 1) {
    const Prim& p = prims[begin];
    Node& n = nodes_[size_t(me)];
    SetBounds(&n, p.lo, p.hi, p.cone.axis, 1, p.power);
    n.triangle = p.index;
    n.p0 = p.p0;
    n.p1 = p.p1;
    n.p2 = p.p2;
    n.ng = p.cone.axis;
    leaf_[size_t(p.index)] = me;
    return me;
  }
  Vec3 lo = prims[begin].lo, hi = prims[begin].hi;
  Vec3 clo = prims[begin].centroid, chi = clo;
  Cone cone;
  float power = 0;
  for (size_t i = begin; i < end; ++i) {
    lo = Min(lo, prims[i].lo);
    hi = Max(hi, prims[i].hi);
    clo = Min(clo, prims[i].centroid);
    chi = Max(chi, prims[i].centroid);
    cone = Union(cone, prims[i].cone);
    power += prims[i].power;
  }
  if (end - begin <= size_t(kBucketTriangles) && cone.cos_half >= kBucketCosCone) {
    Node& n = nodes_[size_t(me)];
    SetBounds(&n, lo, hi, cone.axis, cone.cos_half, power);
    n.bucket = int(buckets_.size());
    for (size_t i = begin; i < end; ++i) {
      buckets_.push_back(
          BucketEntry{prims[i].p0, prims[i].cone.axis, prims[i].power, prims[i].index});
      leaf_[size_t(prims[i].index)] = me;
    }
    return me;
  }
  // The split: the bucket boundary of least surface-area-orientation cost over the three axes;
  // the middle element along the widest axis when the centroids coincide.
  const Vec3 extent = hi - lo;
  const float max_extent = MaxComponent(extent);
  float best_cost = INFINITY;
  int best_axis = -1, best_bucket = -1;
  for (int axis = 0; axis < 3; ++axis) {
    const float span = chi[axis] - clo[axis];
    if (!(span > 0)) continue;
    struct Bucket {
      Vec3 lo{INFINITY, INFINITY, INFINITY}, hi{-INFINITY, -INFINITY, -INFINITY};
      Cone cone;
      float power = 0;
      int count = 0;
    };
    std::array<Bucket, kBuckets> b;
    for (size_t i = begin; i < end; ++i) {
      Bucket& k = b[size_t(BucketOf(prims[i].centroid[axis], clo[axis], span))];
      k.lo = Min(k.lo, prims[i].lo);
      k.hi = Max(k.hi, prims[i].hi);
      k.cone = Union(k.cone, prims[i].cone);
      k.power += prims[i].power;
      ++k.count;
    }
    // Regularisation (Conty Estevez and Kulla): thin slabs along a short axis cost more.
    const float kr = extent[axis] > 0 ? max_extent / extent[axis] : 1.0f;
    for (int split = 1; split < kBuckets; ++split) {
      Bucket l, r;
      for (int k = 0; k < kBuckets; ++k) {
        Bucket& side = k < split ? l : r;
        if (b[size_t(k)].count == 0) continue;
        side.lo = Min(side.lo, b[size_t(k)].lo);
        side.hi = Max(side.hi, b[size_t(k)].hi);
        side.cone = Union(side.cone, b[size_t(k)].cone);
        side.power += b[size_t(k)].power;
        side.count += b[size_t(k)].count;
      }
      if (l.count == 0 || r.count == 0) continue;
      const float cost = kr * (l.power * OrientationMeasure(l.cone) * BoxArea(l.lo, l.hi) +
                               r.power * OrientationMeasure(r.cone) * BoxArea(r.lo, r.hi));
      if (cost < best_cost) {
        best_cost = cost;
        best_axis = axis;
        best_bucket = split;
      }
    }
  }
  size_t mid;
  // Past kMaxCostDepth the range is halved (the depth stays bounded).
  constexpr int kMaxCostDepth = 30;
  if (best_axis >= 0 && depth < kMaxCostDepth) {
    const int axis = best_axis;
    const float span = chi[axis] - clo[axis];
    mid = size_t(std::partition(prims.begin() + long(begin), prims.begin() + long(end),
                                [&](const Prim& p) {
                                  return BucketOf(p.centroid[axis], clo[axis], span) < best_bucket;
                                }) -
                 prims.begin());
  } else {
    mid = begin;
  }
  if (mid == begin || mid == end) {  // coincident centroids (or an empty side): halve the range
    int axis = 0;
    for (int a = 1; a < 3; ++a)
      if (extent[a] > extent[axis]) axis = a;
    mid = (begin + end) / 2;
    std::nth_element(
        prims.begin() + long(begin), prims.begin() + long(mid), prims.begin() + long(end),
        [axis](const Prim& a, const Prim& b) { return a.centroid[axis] < b.centroid[axis]; });
  }
  BuildRange(prims, begin, mid, depth + 1);
  const int second = BuildRange(prims, mid, end, depth + 1);
  Node& n = nodes_[size_t(me)];
  SetBounds(&n, lo, hi, cone.axis, cone.cos_half, power);
  n.second = second;
  return me;
}

void LightTree::SetBounds(Node* node, const Vec3& lo, const Vec3& hi, const Vec3& axis,
                          float cos_cone, float power) const {
  node->centre = (lo + hi) * 0.5f;
  node->half = Max(hi - lo, Vec3()) * 0.5f;
  node->r2 = LengthSquared(node->half);
  node->radius = std::sqrt(node->r2);
  node->axis = axis;
  node->cos_cone = cos_cone;
  node->sin_cone = SafeSqrt(1 - cos_cone * cos_cone);
  const Vec3& h = node->half;
  node->spread = std::abs(axis.x) * h.x + std::abs(axis.y) * h.y + std::abs(axis.z) * h.z +
                 SafeSqrt(2 * (1 - cos_cone)) * node->radius;
  node->power = power;
}

inline float LightTree::NodeImportance(const Node& node, const Vec3& p, const Vec3& n) const {
  const bool has_normal = !IsBlack(n);
  if (node.triangle >= 0 && !TriangleCanLight(node, p, n)) return 0;
  const Vec3& h = node.half;
  const float r2 = node.r2;
  const Vec3 d = p - node.centre;  // from the box towards p
  const float d2 = LengthSquared(d);
  const float dist2 = std::max(d2, r2);
  if (!(dist2 > 0)) return 0;
  // The box's own tests, which hold inside its bounding sphere too. Below p's horizon: every
  // point x of the box has n.(x - p) <= 0 (exact for the box).
  if (has_normal &&
      -Dot(n, d) + std::abs(n.x) * h.x + std::abs(n.y) * h.y + std::abs(n.z) * h.z <= 0)
    return 0;
  // Behind every emitting side: for a normal m of the cone, max over x of m.(p - x) is
  // m.d + sum |m_k| h_k, at most |d| cos(theta_x) + sum |axis_k| h_k + |m - axis| |h| (the
  // node's spread), with theta_x = max(0, angle(axis, d) - cone) and |m - axis| <= 2 sin(cone/2).
  const float cos_o = node.cos_cone, sin_o = node.sin_cone;
  // The sines below come from cross products and the distance, not from 1 - cos^2 of an angle
  // computed first: the four square roots then depend on d alone and run side by side, where in
  // a chain their latency was most of this function's time (perf, make_room 905's tube lamps).
  const float dist = std::sqrt(d2);
  const float inv_dist = dist > 0 ? 1 / dist : 0.0f;
  const float cos_w = dist > 0 ? Dot(node.axis, d) * inv_dist : 1.0f;
  const float sin_w = dist > 0 ? std::sqrt(LengthSquared(Cross(node.axis, d))) * inv_dist : 0.0f;
  const float cos_x = CosMinusClamped(cos_w, sin_w, cos_o, sin_o);
  const float sin_x = SinMinusClamped(cos_w, sin_w, cos_o, sin_o);
  if (dist * cos_x + node.spread <= 0) return 0;
  if (d2 <= r2) return node.power / dist2;  // p inside the bounding sphere: any direction
  // The box seen from p: within the cone of half-angle b around the direction to its centre.
  const float sin_b = node.radius * inv_dist;
  const float cos_b = std::sqrt(d2 - r2) * inv_dist;
  // theta' = max(0, angle(axis, wi) - cone - b): the least angle a normal can make with a
  // direction from the box to p.
  const float cos_e = CosMinusClamped(cos_x, sin_x, cos_b, sin_b);
  if (cos_e <= 0) return 0;  // every triangle emits away from p
  float cos_i = 1;
  if (has_normal) {
    const float c_i = -Dot(n, d) * inv_dist;
    const float s_i = std::sqrt(LengthSquared(Cross(n, d))) * inv_dist;
    cos_i = CosMinusClamped(c_i, s_i, cos_b, sin_b);
    if (cos_i <= 0) return 0;  // the whole box is below p's horizon
  }
  return node.power * cos_e * cos_i * (inv_dist * inv_dist);
}

float LightTree::Importance(const Vec3& p, const Vec3& n) const {
  return nodes_.empty() ? 0.0f : NodeImportance(nodes_[0], p, n);
}

bool LightTree::TriangleCanLight(const Node& node, const Vec3& p, const Vec3& n) const {
  // Exact for one triangle: p behind its emitting side, or all its corners below p's horizon.
  if (Dot(p - node.p0, node.ng) <= 0) return false;
  return IsBlack(n) || Dot(node.p0 - p, n) > 0 || Dot(node.p1 - p, n) > 0 ||
         Dot(node.p2 - p, n) > 0;
}

void LightTree::LaneImportances(const WideNode& w, const Vec3& p, const Vec3& n,
                                float out[4]) const {
  // NodeImportance's steps for four nodes at once (see there); a lane failing a test is 0.
  const bool has_normal = !IsBlack(n);
  const Float4 zero(0.0f), one(1.0f);
  const Float4 dx = Float4(p.x) - Float4::Load(w.cx);
  const Float4 dy = Float4(p.y) - Float4::Load(w.cy);
  const Float4 dz = Float4(p.z) - Float4::Load(w.cz);
  const Float4 d2 = dx * dx + dy * dy + dz * dz;
  const Float4 r2 = Float4::Load(w.r2);
  const Float4 dist2 = Max(d2, r2);
  Float4 ok = dist2 > zero;
  const Float4 nx(n.x), ny(n.y), nz(n.z);
  const Float4 n_dot_d = nx * dx + ny * dy + nz * dz;
  if (has_normal) {  // the box below p's horizon
    const Float4 top = zero - n_dot_d + Float4(std::abs(n.x)) * Float4::Load(w.hx) +
                       Float4(std::abs(n.y)) * Float4::Load(w.hy) +
                       Float4(std::abs(n.z)) * Float4::Load(w.hz);
    ok = ok & (top > zero);
  }
  const Float4 dist = Sqrt(d2);
  const Float4 positive = dist > zero;
  const Float4 inv_dist = Select(positive, one / dist, zero);
  const Float4 ax = Float4::Load(w.ax), ay = Float4::Load(w.ay), az = Float4::Load(w.az);
  const Float4 kx = ay * dz - az * dy, ky = az * dx - ax * dz, kz = ax * dy - ay * dx;
  const Float4 cos_w = Select(positive, (ax * dx + ay * dy + az * dz) * inv_dist, one);
  const Float4 sin_w = Select(positive, Sqrt(kx * kx + ky * ky + kz * kz) * inv_dist, zero);
  const Float4 cos_o = Float4::Load(w.cos_cone), sin_o = Float4::Load(w.sin_cone);
  const Float4 within = cos_w >= cos_o;
  const Float4 cos_x = Select(within, one, cos_w * cos_o + sin_w * sin_o);
  const Float4 sin_x = Select(within, zero, sin_w * cos_o - cos_w * sin_o);
  ok = ok & (dist * cos_x + Float4::Load(w.spread) > zero);  // behind every emitting side
  const Float4 power = Float4::Load(w.power);
  const Float4 inside = d2 <= r2;  // p inside the bounding sphere: any direction
  const Float4 sin_b = Float4::Load(w.radius) * inv_dist;
  const Float4 cos_b = Sqrt(Max(d2 - r2, zero)) * inv_dist;
  const Float4 cos_e = Select(cos_x >= cos_b, one, cos_x * cos_b + sin_x * sin_b);
  Float4 seen = cos_e > zero;
  Float4 cos_i = one;
  if (has_normal) {
    const Float4 c_i = (zero - n_dot_d) * inv_dist;
    const Float4 mx = ny * dz - nz * dy, my = nz * dx - nx * dz, mz = nx * dy - ny * dx;
    const Float4 s_i = Sqrt(mx * mx + my * my + mz * mz) * inv_dist;
    cos_i = Select(c_i >= cos_b, one, c_i * cos_b + s_i * sin_b);
    seen = seen & (cos_i > zero);
  }
  const Float4 value = Select(inside, power / dist2, power * cos_e * cos_i * (inv_dist * inv_dist));
  Select(ok & (inside | seen), value, zero).Store(out);
  for (int k = w.count; k < 4; ++k) out[k] = 0;
  for (unsigned bits = w.triangle_lanes; bits != 0; bits &= bits - 1) {
    const int k = __builtin_ctz(bits);
    if (out[k] > 0 && !TriangleCanLight(nodes_[size_t(w.node[k])], p, n)) out[k] = 0;
  }
}

int LightTree::PickInBucket(const Node& node, const Vec3& p, float u, int wanted, float* prob,
                            float* u_rest) const {
  *prob = 0;
  const BucketEntry* e = &buckets_[size_t(node.bucket)];
  float w[kBucketTriangles], total = 0;
  for (int k = 0; k < node.count; ++k) {
    w[k] = Dot(p - e[k].p0, e[k].ng) > 0 ? e[k].power : 0.0f;
    total += w[k];
  }
  if (!(total > 0)) return -1;
  if (wanted >= 0) {
    for (int k = 0; k < node.count; ++k)
      if (e[k].triangle == wanted) *prob = w[k] / total;
    return -1;
  }
  // The first facing entry whose running sum passes u x total (the last facing one when
  // rounding leaves u x total past the sum).
  const float target = u * total;
  float run = 0;
  int pick = -1;
  float before = 0;
  for (int k = 0; k < node.count; ++k) {
    if (!(w[k] > 0)) continue;
    pick = k;
    before = run;
    run += w[k];
    if (target < run) break;
  }
  *prob = w[pick] / total;
  if (u_rest) *u_rest = std::clamp((target - before) / w[pick], 0.0f, 0x1.fffffep-1f);
  return e[pick].triangle;
}

int LightTree::LastAtOrBelow(const double* cum, int count, float u, double target) {
  // First a guess as if the triangles had equal powers (a tessellated tube or disk: then it is
  // right, or one off by rounding), checked against its two bounds; else a binary search without
  // branches (its halving steps compile to conditional moves). std::upper_bound over the 512
  // triangles of a tube, with a mispredicted branch at each step, was half of Sample's own time
  // in `path` on make_room 910 (perf).
  const int guess = std::min(count - 1, int(u * float(count)));
  for (int k = std::max(0, guess - 1); k <= std::min(count - 1, guess + 1); ++k)
    if (cum[k] <= target && (k + 1 == count || cum[k + 1] > target)) return k;
  int at_or_below = 0;
  for (int left = count; left > 1;) {
    const int half = left / 2;
    at_or_below = cum[at_or_below + half] <= target ? at_or_below + half : at_or_below;
    left -= half;
  }
  return at_or_below;
}

int LightTree::Sample(const Vec3& p, const Vec3& n, float u, float* pmf, bool stop_far,
                      float* u_rest) const {
  *pmf = 0;
  // No test of the root here (the callers have made it: LightSampler::Weight), nor in Pmf.
  if (nodes_.empty()) return -1;
  int at = 0;  // the binary leaf reached
  float prob = 1;
  for (int wi = wide_.empty() ? -1 : 0; wi >= 0;) {
    const WideNode& w = wide_[size_t(wi)];
    const Node& node = nodes_[size_t(w.binary)];
    if (stop_far && StopsAt(node, p)) {  // pick among the node's triangles by power
      const double lo = cum_[size_t(node.first)], hi = cum_[size_t(node.first + node.count)];
      const double target = lo + double(u) * (hi - lo);
      const int k = node.first + LastAtOrBelow(cum_.data() + node.first, node.count, u, target);
      const int triangle = order_[size_t(k)];
      prob *= RangeProbability(node, triangle);
      if (!(prob > 0)) return -1;
      *pmf = prob;
      if (u_rest) {
        const double width = cum_[size_t(k + 1)] - cum_[size_t(k)];
        *u_rest = std::clamp(float((target - cum_[size_t(k)]) / width), 0.0f, 0x1.fffffep-1f);
      }
      return triangle;
    }
    float imp[4];
    LaneImportances(w, p, n, imp);
    const float total = imp[0] + imp[1] + imp[2] + imp[3];
    if (!(total > 0)) return -1;
    // The first lane with importance whose running sum passes u x total (the last such lane when
    // rounding leaves u x total past the sum).
    const float target = u * total;
    float run = 0;
    int lane = -1;
    for (int k = 0; k < w.count; ++k) {
      if (!(imp[k] > 0)) continue;
      lane = k;
      if (target < run + imp[k]) break;
      run += imp[k];
    }
    u = std::clamp((target - run) / imp[lane], 0.0f, 0x1.fffffep-1f);
    prob *= imp[lane] / total;
    wi = w.child[lane];
    if (wi < 0) at = -1 - wi;
  }
  const Node& leaf = nodes_[size_t(at)];
  int triangle = leaf.triangle;
  if (leaf.bucket >= 0) {
    float in_bucket = 0;
    triangle = PickInBucket(leaf, p, u, -1, &in_bucket, u_rest);
    prob *= in_bucket;
  } else if (u_rest) {
    *u_rest = u;
  }
  if (triangle < 0 || !(prob > 0)) return -1;
  *pmf = prob;
  return triangle;
}

float LightTree::Pmf(const Vec3& p, const Vec3& n, unsigned index, bool stop_far) const {
  if (index >= leaf_.size() || leaf_[index] < 0) return 0;
  const int position = position_[index];
  int at = 0;
  float prob = 1;
  for (int wi = wide_.empty() ? -1 : 0; wi >= 0;) {
    const WideNode& w = wide_[size_t(wi)];
    if (stop_far && StopsAt(nodes_[size_t(w.binary)], p))
      return prob * RangeProbability(nodes_[size_t(w.binary)], int(index));
    float imp[4];
    LaneImportances(w, p, n, imp);
    const float total = imp[0] + imp[1] + imp[2] + imp[3];
    if (!(total > 0)) return 0;
    int lane = 0;
    while (lane + 1 < w.count) {
      const Node& l = nodes_[size_t(w.node[lane])];
      if (position < l.first + l.count) break;
      ++lane;
    }
    if (!(imp[lane] > 0)) return 0;
    prob *= imp[lane] / total;
    wi = w.child[lane];
    if (wi < 0) at = -1 - wi;
  }
  const Node& leaf = nodes_[size_t(at)];
  if (leaf.bucket >= 0) {
    float in_bucket = 0;
    PickInBucket(leaf, p, 0, int(index), &in_bucket);
    prob *= in_bucket;
  }
  return prob;
}

}  // namespace irfarm
