// OpenMesh decimation modules of bodybuilder, and the driver that runs them.
//
// FastDecimaterT runs the collapses in passes, as meshoptimizer's simplifier does: each pass
// ranks every edge once by the error of its cheaper direction (the removed vertex's quadric at
// the survivor), sorts them, and collapses in that order while the error stays below 1.5 times
// the error at the rank that would reach the target, touching each vertex at most once per pass
// (no collapse is ranked on a neighbourhood that already changed). A refused candidate (topology,
// normal rules, skin weights) does not count towards that rank. Against our former greedy driver
// (one heap entry per vertex, re-evaluated after each collapse) this is 4-6 times faster and
// spreads the collapses evenly over the surface. The topology test is OpenMesh's
// TriConnectivity::is_collapse_ok (which allocates and compares strings on every call in
// OpenMesh 9) rewritten: locked vertex, deleted elements, the link condition, boundary cases,
// the tetrahedron case, at least two faces at v0.
// A collapse that would leave an input vertex absorbed by the removed vertex, or by one of its
// other neighbours, farther from the new faces than the pass's error goal is deferred to a later
// pass (the quadric alone let thin tips slide back: bench_decimate 8 -> 11 of 12 rows no worse
// than meshoptimizer on Hausdorff, at 1.8x the time). The ratio (set_member_k, decimate.h's
// Options::member_k) is 1 by default; extremities.h also tries 0 and 2 and keeps whichever
// result measures nearest. decimate_in_passes may call back after each pass (decimate.h's
// snapshot), which changes nothing in the passes.
//
// ModSkinWeightsT forbids collapsing two vertices whose skin weights differ by more than a
// threshold (L1 distance of the influence distributions). Human-specific: it keeps the vertex
// rings at elbows, knees and wrists, where the weights change fast, so that the decimated
// extremity still bends like the full one.
//
// ModQuadricNormalizedT is the priority module: Garland-Heckbert quadrics of face planes weighted
// by the square root of their area (meshoptimizer's weighting), and the priority is the REMOVED
// vertex's quadric at the survivor divided by its planes' weight: a mean squared distance, as
// meshoptimizer ranks collapses. (ModQuadricT sums both vertices' quadrics unnormalized, which
// favours collapses among small triangles and penalizes survivors that already absorbed
// neighbours.) It also does the normal rules in the same pass over the faces: no face turns more
// than a given angle in one collapse (ModNormalFlippingT's rule), nor away from the mean of the
// ORIGINAL normals of its vertices (many small turns cannot add up to a flip). After the passes,
// polish() lets each survivor take the place of the absorbed input vertex that best fits its
// accumulated quadric (survivors stay input vertices, with all their attributes).
#pragma once

#include <OpenMesh/Core/Geometry/QuadricT.hh>
#include <OpenMesh/Core/Utils/Property.hh>
#include <OpenMesh/Tools/Decimater/BaseDecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModBaseT.hh>

#include <algorithm>
#include <array>
#include <cfloat>
#include <cstdint>
#include <vector>
#include <cmath>
#include <utility>

namespace bb::decimate::detail {

// A vertex's influences as (joint, weight) pairs.
using Influences = std::array<std::pair<int, float>, 4>;

inline float influence_distance(const Influences& a, const Influences& b) {
  float d = 0;
  for (const auto& [j, w] : a) {
    if (w == 0) continue;
    float wb = 0;
    for (const auto& [k, v] : b) if (k == j) wb += v;
    d += std::abs(w - wb);
  }
  for (const auto& [k, v] : b) {
    if (v == 0) continue;
    bool in_a = false;
    for (const auto& [j, w] : a) in_a |= (j == k && w != 0);
    if (!in_a) d += v;
  }
  return d;
}

template <typename MeshT>
class ModSkinWeightsT : public OpenMesh::Decimater::ModBaseT<MeshT> {
 public:
  DECIMATING_MODULE(ModSkinWeightsT, MeshT, SkinWeights);

  explicit ModSkinWeightsT(MeshT& mesh) : Base(mesh, true) {}

  void set_property(OpenMesh::VPropHandleT<Influences> p) { prop_ = p; }
  void set_max_difference(float d) { max_difference_ = d; }

  float collapse_priority(const CollapseInfo& ci) override {
    const auto& a = Base::mesh().property(prop_, ci.v0);
    const auto& b = Base::mesh().property(prop_, ci.v1);
    return influence_distance(a, b) > max_difference_ ? float(Base::ILLEGAL_COLLAPSE)
                                                      : float(Base::LEGAL_COLLAPSE);
  }

 private:
  OpenMesh::VPropHandleT<Influences> prop_;
  float max_difference_ = 0.6f;
};

template <typename MeshT>
class ModQuadricNormalizedT : public OpenMesh::Decimater::ModBaseT<MeshT> {
 public:
  DECIMATING_MODULE(ModQuadricNormalizedT, MeshT, QuadricNormalized);
  using Point = typename MeshT::Point;
  using Normal = typename MeshT::Normal;
  using Quadric = OpenMesh::Geometry::Quadricd;

  explicit ModQuadricNormalizedT(MeshT& mesh) : Base(mesh, false) {
    mesh.add_property(quadric_);
    mesh.add_property(area_);
  }
  ~ModQuadricNormalizedT() override {
    Base::mesh().remove_property(quadric_);
    Base::mesh().remove_property(area_);
  }

  void set_original_normals(OpenMesh::VPropHandleT<Normal> p) { original_ = p; }
  void set_max_flip_deg(double deg) { min_cos_flip_ = std::cos(deg * 3.14159265358979 / 180.0); }
  void set_max_original_deviation_deg(double deg) { min_cos_original_ = std::cos(deg * 3.14159265358979 / 180.0); }
  // Root-mean-square distance (metres) of the merged vertex to its planes above which a collapse
  // is refused; 0: no bound.
  void set_max_error(double metres) { max_error2_ = metres * metres; }
  double max_error2() const { return max_error2_; }
  // Plane weight: face area (false) or its square root (true, the default, as meshoptimizer:
  // the error then scales like a length, which keeps small curved features, ears and
  // fingertips, against large flat areas).
  void set_sqrt_area_weights(bool on) { sqrt_area_ = on; }

  // Mean squared distance (m^2) of p1 to the planes v0 stands for.
  double error(typename MeshT::VertexHandle v0, const Point& p1) {
    const MeshT& m = Base::mesh();
    double w = m.property(area_, v0);
    return w > 1e-30 ? std::max(0.0, m.property(quadric_, v0)(p1)) / w : 0.0;
  }

  void initialize() override {
    MeshT& m = Base::mesh();
    next_member_.assign(m.n_vertices(), -1);
    last_member_.resize(m.n_vertices());
    for (size_t i = 0; i < last_member_.size(); ++i) last_member_[i] = static_cast<int>(i);
    for (auto v : m.vertices()) {
      m.property(quadric_, v).clear();
      m.property(area_, v) = 0;
    }
    for (auto f : m.faces()) {
      auto h = m.halfedge_handle(f);
      auto v0 = m.to_vertex_handle(h), v1 = m.to_vertex_handle(m.next_halfedge_handle(h)),
           v2 = m.from_vertex_handle(h);
      Point a = m.point(v0), b = m.point(v1), c = m.point(v2);
      Point n = (b - a) % (c - a);
      double area = n.norm();
      if (area <= 1e-30) continue;
      n /= area;
      area *= 0.5;
      if (sqrt_area_) area = std::sqrt(area);
      Quadric q(n[0], n[1], n[2], -(a | n));
      q *= area;
      for (auto v : {v0, v1, v2}) {
        m.property(quadric_, v) += q;
        m.property(area_, v) += area;
      }
    }
  }

  // Mean squared distance (m^2) of p1 to the planes v0 stands for (v0's quadric over their area),
  // or ILLEGAL_COLLAPSE when a surrounding face would degenerate, flip or turn away from its
  // vertices' original normals.
  float collapse_priority(const CollapseInfo& ci) override {
    MeshT& m = Base::mesh();
    const Quadric& q = m.property(quadric_, ci.v0);
    double area = std::max(1e-30, m.property(area_, ci.v0));
    double e = std::max(0.0, q(ci.p1)) / area;
    if (max_error2_ > 0 && e > max_error2_) return float(Base::ILLEGAL_COLLAPSE);
    if (!normals_ok(ci)) return float(Base::ILLEGAL_COLLAPSE);
    return float(e);
  }

  void preprocess_collapse(const CollapseInfo& ci) override {
    MeshT& m = Base::mesh();
    m.property(quadric_, ci.v1) += m.property(quadric_, ci.v0);
    m.property(area_, ci.v1) += m.property(area_, ci.v0);
    next_member_[last_member_[ci.v1.idx()]] = ci.v0.idx();
    last_member_[ci.v1.idx()] = last_member_[ci.v0.idx()];
  }

  // After decimation: every surviving unlocked vertex moves to the position of the input vertex,
  // among those it absorbed (itself included) and `allowed(v, member)`, where its accumulated
  // quadric is smallest, unless a face around it would then degenerate, flip or turn away from
  // original normals. `moved(v, member)` is called for each move (the caller carries the member's
  // attributes over; this module updates the point and original normal). Returns the moves.
  template <typename Allowed, typename Moved>
  size_t polish(Allowed&& allowed, Moved&& moved) {
    MeshT& m = Base::mesh();
    size_t moves = 0;
    for (auto v : m.vertices()) {
      if (m.status(v).deleted() || m.status(v).locked() || next_member_[v.idx()] < 0) continue;
      const Quadric& q = m.property(quadric_, v);
      double best = q(m.point(v));
      std::vector<int> order;
      for (int k = next_member_[v.idx()]; k >= 0; k = next_member_[k]) {
        typename MeshT::VertexHandle mv(k);
        double e = q(m.point(mv));
        if (e < best * 0.999 && allowed(v, mv)) order.push_back(k);
      }
      std::sort(order.begin(), order.end(), [&](int a, int b) {
        return q(m.point(typename MeshT::VertexHandle(a))) < q(m.point(typename MeshT::VertexHandle(b)));
      });
      for (int k : order) {
        typename MeshT::VertexHandle mv(k);
        Normal on = original_.is_valid() ? m.property(original_, mv) : Normal(0, 0, 0);
        if (!move_ok(v, m.point(mv), on)) continue;
        m.set_point(v, m.point(mv));
        if (original_.is_valid()) m.property(original_, v) = on;
        moved(v, mv);
        ++moves;
        break;
      }
    }
    return moves;
  }

  // Ratio of a member's squared distance to the pass's error goal above which the pass driver
  // defers a collapse (0: no such rule). 1 beat 2, 4, 9 and 25 on bench_decimate's two tables.
  void set_member_k(double k) { member_k_ = k; }
  double member_k() const { return member_k_; }

  // Largest squared distance from the input vertices absorbed by v0 to the faces around v1
  // after the collapse (v0's faces with v0 at p1, and v1's others), and from those absorbed by
  // v0's other neighbours to the faces around their own vertex after the collapse (they may
  // have been nearest to v0's faces). Survivors do not move before polish(), so each member's
  // point is still its input position. (Also measuring v1's members did not help.)
  double member_distance2(const CollapseInfo& ci) {
    MeshT& m = Base::mesh();
    fan_.clear();
    for (auto fh : m.vf_range(ci.v0)) {
      if (fh == ci.fl || fh == ci.fr) continue;
      std::array<Point, 3> t;
      int k = 0;
      for (auto v : m.fv_range(fh)) t[k++] = v == ci.v0 ? ci.p1 : m.point(v);
      fan_.push_back(t);
    }
    for (auto fh : m.vf_range(ci.v1)) {
      if (fh == ci.fl || fh == ci.fr) continue;
      std::array<Point, 3> t;
      int k = 0;
      for (auto v : m.fv_range(fh)) t[k++] = m.point(v);
      fan_.push_back(t);
    }
    if (fan_.empty()) return 0;
    double worst = 0;
    auto scan = [&](typename MeshT::VertexHandle s, const std::vector<std::array<Point, 3>>& faces) {
      for (int k = s.idx(); k >= 0; k = next_member_[k]) {
        if (k == s.idx() && s != ci.v0) continue;  // a vertex of the faces
        const Point& p = m.point(typename MeshT::VertexHandle(k));
        double best = DBL_MAX;
        for (const auto& t : faces) {
          best = std::min(best, point_triangle_distance2(p, t[0], t[1], t[2]));
          if (best <= worst) break;
        }
        worst = std::max(worst, best);
      }
    };
    scan(ci.v0, fan_);
    for (auto w : m.vv_range(ci.v0)) {
      if (w == ci.v1 || next_member_[w.idx()] < 0) continue;
      local_.clear();
      for (auto fh : m.vf_range(w)) {
        if (fh == ci.fl || fh == ci.fr) continue;
        std::array<Point, 3> t;
        int k = 0;
        for (auto v : m.fv_range(fh)) t[k++] = v == ci.v0 ? ci.p1 : m.point(v);
        local_.push_back(t);
      }
      if (!local_.empty()) scan(w, local_);
    }
    return worst;
  }

  // Squared distance from p to the triangle abc (Ericson, Real-Time Collision Detection 5.1.5).
  static double point_triangle_distance2(const Point& p, const Point& a, const Point& b, const Point& c) {
    Point ab = b - a, ac = c - a, ap = p - a;
    double d1 = ab | ap, d2 = ac | ap;
    if (d1 <= 0 && d2 <= 0) return ap.sqrnorm();
    Point bp = p - b;
    double d3 = ab | bp, d4 = ac | bp;
    if (d3 >= 0 && d4 <= d3) return bp.sqrnorm();
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) return (ap - ab * (d1 / (d1 - d3))).sqrnorm();
    Point cp = p - c;
    double d5 = ab | cp, d6 = ac | cp;
    if (d6 >= 0 && d5 <= d6) return cp.sqrnorm();
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) return (ap - ac * (d2 / (d2 - d6))).sqrnorm();
    double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
      return (bp - (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)))).sqrnorm();
    double denom = 1.0 / (va + vb + vc);
    double v = vb * denom, w = vc * denom;
    return (ap - ab * v - ac * w).sqrnorm();
  }

  // The faces around v0 that survive the collapse, with v0 at p1.
  bool normals_ok(const CollapseInfo& ci) {
    MeshT& m = Base::mesh();
    for (auto fh : m.vf_range(ci.v0)) {
      if (fh == ci.fl || fh == ci.fr) continue;
      Point p[3], old[3];
      typename MeshT::VertexHandle vs[3];
      int k = 0;
      for (auto v : m.fv_range(fh)) {
        vs[k] = v == ci.v0 ? ci.v1 : v;
        old[k] = m.point(v);
        p[k] = v == ci.v0 ? ci.p1 : old[k];
        ++k;
      }
      Point nn = (p[1] - p[0]) % (p[2] - p[0]);
      Point no = (old[1] - old[0]) % (old[2] - old[0]);
      double ln = nn.norm(), lo = no.norm();
      if (ln <= 1e-12 * lo || ln <= 1e-24) return false;
      nn /= ln;
      if (lo > 0 && (nn | (no / lo)) < min_cos_flip_) return false;
      if (original_.is_valid() && !original_ok(nn, m.property(original_, vs[0]), m.property(original_, vs[1]), m.property(original_, vs[2]))) return false;
    }
    return true;
  }

  // The unit face normal nn is within the bound of the mean of its vertices' original normals
  // a, b, c. (Each normal on its own was too strict on fingers: across a thin finger the vertex
  // normals spread by more than the bound, and the refused collapses cost 30 % of mean error at
  // 5 % of the hand's triangles.)
  bool original_ok(const Point& nn, const Normal& a, const Normal& b, const Normal& c) const {
    Normal sum = a + b + c;
    double l = sum.norm();
    return l <= 0 || (nn | sum) >= min_cos_original_ * l;
  }

  // The faces around v with v at p (and its original normal `on`) pass the normal rules.
  bool move_ok(typename MeshT::VertexHandle v, const Point& p, const Normal& on) {
    MeshT& m = Base::mesh();
    for (auto fh : m.vf_range(v)) {
      Point q[3], old[3];
      typename MeshT::VertexHandle vs[3];
      int k = 0;
      for (auto w : m.fv_range(fh)) {
        vs[k] = w;
        old[k] = m.point(w);
        q[k] = w == v ? p : old[k];
        ++k;
      }
      Point nn = (q[1] - q[0]) % (q[2] - q[0]);
      Point no = (old[1] - old[0]) % (old[2] - old[0]);
      double ln = nn.norm(), lo = no.norm();
      if (ln <= 1e-12 * lo || ln <= 1e-24) return false;
      nn /= ln;
      if (lo > 0 && (nn | (no / lo)) < min_cos_flip_) return false;
      if (original_.is_valid()) {
        Normal o[3];
        for (int j = 0; j < 3; ++j) o[j] = vs[j] == v ? on : m.property(original_, vs[j]);
        if (!original_ok(nn, o[0], o[1], o[2])) return false;
      }
    }
    return true;
  }

 private:
  std::vector<int> next_member_, last_member_;
  std::vector<std::array<Point, 3>> fan_;
  std::vector<std::array<Point, 3>> local_;
  OpenMesh::VPropHandleT<Quadric> quadric_;
  OpenMesh::VPropHandleT<double> area_;
  OpenMesh::VPropHandleT<Normal> original_;
  double min_cos_flip_ = 0.5, min_cos_original_ = 0.0, max_error2_ = 0, member_k_ = 1.0;
  bool sqrt_area_ = true;
};

template <typename MeshT>
class FastDecimaterT : public OpenMesh::Decimater::BaseDecimaterT<MeshT> {
 public:
  using Base = OpenMesh::Decimater::BaseDecimaterT<MeshT>;
  using CollapseInfo = OpenMesh::Decimater::CollapseInfoT<MeshT>;
  using HalfedgeHandle = typename MeshT::HalfedgeHandle;
  using VertexHandle = typename MeshT::VertexHandle;

  explicit FastDecimaterT(MeshT& mesh) : Base(mesh) {}

  size_t decimate_in_passes(size_t target_faces, ModQuadricNormalizedT<MeshT>& quadric) {
    return decimate_in_passes(target_faces, quadric, [](size_t) {});
  }

  // Collapses in passes until at most `target_faces` faces are left (0: while a legal collapse
  // is left), ranking with `quadric`'s error alone. `after_pass(faces)` is called after each pass
  // (the passes do not depend on it). Returns the number of collapses.
  template <typename AfterPass>
  size_t decimate_in_passes(size_t target_faces, ModQuadricNormalizedT<MeshT>& quadric, AfterPass&& after_pass) {
    MeshT& m = Base::mesh();
    const size_t nv = m.n_vertices();
    tag_.assign(nv, 0);
    std::vector<uint8_t> touched(nv, 0);
    struct Candidate {
      float error;
      HalfedgeHandle h;
    };
    std::vector<Candidate> cands;
    size_t nf = 0;
    for (auto f : m.faces()) nf += !m.status(f).deleted();
    size_t collapses = 0;
    const double limit = quadric.max_error2() > 0 ? quadric.max_error2() : DBL_MAX;
    // A collapse that would leave an absorbed input vertex farther from the surface than
    // sqrt(member_k times the pass's error goal) waits for a later pass (see member_distance2);
    // once a pass has nothing but such collapses left, the rule is dropped.
    double member_k = quadric.member_k();
    while (target_faces == 0 || nf > target_faces) {
      cands.clear();
      for (auto e : m.edges()) {
        if (m.status(e).deleted()) continue;
        HalfedgeHandle h0 = m.halfedge_handle(e, 0), h1 = m.halfedge_handle(e, 1);
        VertexHandle a = m.from_vertex_handle(h0), b = m.to_vertex_handle(h0);
        bool la = m.status(a).locked(), lb = m.status(b).locked();
        if (la && lb) continue;
        double ea = la ? DBL_MAX : quadric.error(a, m.point(b));
        double eb = lb ? DBL_MAX : quadric.error(b, m.point(a));
        if (ea <= eb) cands.push_back({float(ea), h0});
        else cands.push_back({float(eb), h1});
      }
      if (cands.empty()) break;
      std::sort(cands.begin(), cands.end(), [](const Candidate& x, const Candidate& y) { return x.error < y.error; });
      const size_t triangle_goal = target_faces == 0 ? SIZE_MAX : nf - target_faces;
      // Most collapses remove two faces: the error of the collapse at that rank, times 1.5 (many
      // candidates are skipped because a neighbour already moved), bounds the pass.
      size_t edge_goal = target_faces == 0 ? SIZE_MAX : triangle_goal / 2;
      std::fill(touched.begin(), touched.end(), 0);
      size_t removed = 0, pass_collapses = 0, deferred = 0;
      for (const Candidate& c : cands) {
        if (c.error > limit) break;
        if (removed >= triangle_goal) break;
        float goal = edge_goal < cands.size() ? 1.5f * cands[edge_goal].error : FLT_MAX;
        if (c.error > goal && removed > triangle_goal / 6) break;
        HalfedgeHandle h = c.h;
        VertexHandle v0 = m.from_vertex_handle(h), v1 = m.to_vertex_handle(h);
        if (touched[v0.idx()] || touched[v1.idx()]) continue;
        CollapseInfo ci(m, h);
        if (!legal(ci) || this->collapse_priority(ci) < 0) {
          ++edge_goal;  // refused: it does not count towards the goal's rank
          continue;
        }
        if (member_k > 0 && goal < FLT_MAX && quadric.member_distance2(ci) > member_k * goal) {
          ++edge_goal;
          ++deferred;
          continue;
        }
        size_t gone = (m.is_boundary(ci.v0v1) || m.is_boundary(ci.v1v0)) ? 1 : 2;
        this->preprocess_collapse(ci);
        m.collapse(ci.v0v1);
        this->postprocess_collapse(ci);
        touched[ci.v0.idx()] = touched[ci.v1.idx()] = 1;
        removed += gone;
        nf -= gone;
        ++pass_collapses;
      }
      collapses += pass_collapses;
      after_pass(nf);
      if (pass_collapses == 0) {
        if (deferred == 0) break;
        member_k = 0;  // only deferred collapses are left: drop the rule
      }
    }
    return collapses;
  }

 private:
  // BaseDecimaterT::is_collapse_legal with TriConnectivity::is_collapse_ok inlined.
  bool legal(const CollapseInfo& ci) {
    MeshT& m = Base::mesh();
    if (m.status(ci.v0).locked()) return false;
    if (m.status(m.edge_handle(ci.v0v1)).deleted() || m.status(ci.v0).deleted() || m.status(ci.v1).deleted())
      return false;
    VertexHandle vl, vr;
    // The edges v1-vl and vl-v0 must not both be boundary edges; nor v0-vr and vr-v1.
    if (!m.is_boundary(ci.v0v1)) {
      HalfedgeHandle h1 = m.next_halfedge_handle(ci.v0v1), h2 = m.next_halfedge_handle(h1);
      vl = m.to_vertex_handle(h1);
      if (m.is_boundary(m.opposite_halfedge_handle(h1)) && m.is_boundary(m.opposite_halfedge_handle(h2))) return false;
    }
    if (!m.is_boundary(ci.v1v0)) {
      HalfedgeHandle h1 = m.next_halfedge_handle(ci.v1v0), h2 = m.next_halfedge_handle(h1);
      vr = m.to_vertex_handle(h1);
      if (m.is_boundary(m.opposite_halfedge_handle(h1)) && m.is_boundary(m.opposite_halfedge_handle(h2))) return false;
    }
    if (vl == vr) return false;  // equal, or both invalid
    const bool b0 = m.is_boundary(ci.v0), b1 = m.is_boundary(ci.v1);
    // An edge between two boundary vertices must be a boundary edge.
    if (b0 && b1 && !m.is_boundary(ci.v0v1) && !m.is_boundary(ci.v1v0)) return false;
    // Link condition: v0 and v1 share no neighbour but vl and vr.
    if (++tag_counter_ == 0) {
      std::fill(tag_.begin(), tag_.end(), 0);
      tag_counter_ = 1;
    }
    for (auto w : m.vv_range(ci.v1)) tag_[w.idx()] = tag_counter_;
    for (auto w : m.vv_range(ci.v0))
      if (tag_[w.idx()] == tag_counter_ && w != vl && w != vr) return false;
    // A tetrahedron would collapse into a doubled triangle.
    if (ci.vl.is_valid() && ci.vr.is_valid() && m.find_halfedge(ci.vl, ci.vr).is_valid() && m.valence(ci.vl) == 3 &&
        m.valence(ci.vr) == 3)
      return false;
    if (b0) {
      if (!b1) return false;                             // boundary into interior
      if (ci.vl.is_valid() && ci.vr.is_valid()) return false;  // only one ring intersection
    }
    // At least two faces at v0.
    if (m.cw_rotated_halfedge_handle(m.cw_rotated_halfedge_handle(ci.v0v1)) == ci.v0v1) return false;
    return true;
  }

  std::vector<uint32_t> tag_;
  uint32_t tag_counter_ = 0;
};

}  // namespace bb::decimate::detail
