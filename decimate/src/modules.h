// OpenMesh decimation modules of bodybuilder, and the driver that runs them.
//
// FastDecimaterT is OpenMesh's DecimaterT (one heap entry per vertex: its cheapest legal
// collapse; after a collapse the removed vertex's ring is re-evaluated) with its own test of the
// collapse's topology: TriConnectivity::is_collapse_ok of OpenMesh 9 allocates and compares
// strings on every call, which made it the largest single cost of decimation here. The test is
// the same (locked vertex, deleted elements, the link condition, boundary cases, the tetrahedron
// case, at least two faces at v0), with a reusable tag array for the one-ring intersection.
//
// ModSkinWeightsT forbids collapsing two vertices whose skin weights differ by more than a
// threshold (L1 distance of the influence distributions). Human-specific: it keeps the vertex
// rings at elbows, knees and wrists, where the weights change fast, so that the decimated
// extremity still bends like the full one.
//
// ModQuadricNormalizedT is the priority module: Garland-Heckbert quadrics of area-weighted face
// planes like ModQuadricT, but the priority is the REMOVED vertex's quadric at the survivor divided
// by its planes' area: a mean squared distance, as meshoptimizer ranks collapses. ModQuadricT
// sums both vertices' quadrics unnormalized, which favours collapses among small triangles and
// penalizes survivors that already absorbed neighbours; on our extremities its Hausdorff error was
// worse than meshoptimizer's at all 12 benchmark points, this rule's at 6 of 12. It also does
// the normal rules in the same pass over the faces: no face turns more than a given angle in one
// collapse (ModNormalFlippingT's rule), nor away from the ORIGINAL normals of its vertices (many
// small turns cannot add up to a flip).
#pragma once

#include <OpenMesh/Core/Geometry/QuadricT.hh>
#include <OpenMesh/Core/Utils/Property.hh>
#include <OpenMesh/Tools/Decimater/BaseDecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModBaseT.hh>

#include <algorithm>
#include <array>
#include <cfloat>
#include <cstdint>
#include <queue>
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

  void initialize() override {
    MeshT& m = Base::mesh();
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
  }

 private:
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
      if (original_.is_valid())
        for (int j = 0; j < 3; ++j)
          if ((nn | m.property(original_, vs[j])) < min_cos_original_) return false;
    }
    return true;
  }

  OpenMesh::VPropHandleT<Quadric> quadric_;
  OpenMesh::VPropHandleT<double> area_;
  OpenMesh::VPropHandleT<Normal> original_;
  double min_cos_flip_ = 0.5, min_cos_original_ = 0.0, max_error2_ = 0;
};

template <typename MeshT>
class FastDecimaterT : public OpenMesh::Decimater::BaseDecimaterT<MeshT> {
 public:
  using Base = OpenMesh::Decimater::BaseDecimaterT<MeshT>;
  using CollapseInfo = OpenMesh::Decimater::CollapseInfoT<MeshT>;
  using HalfedgeHandle = typename MeshT::HalfedgeHandle;
  using VertexHandle = typename MeshT::VertexHandle;

  explicit FastDecimaterT(MeshT& mesh) : Base(mesh) {}

  // Collapses until at most `target_faces` faces are left (0: while a legal collapse is left).
  // Returns the number of collapses. Call initialize() first.
  size_t decimate_to_faces(size_t target_faces) {
    MeshT& m = Base::mesh();
    const size_t nv = m.n_vertices();
    tag_.assign(nv, 0);
    stamp_.assign(nv, 0);
    target_.assign(nv, HalfedgeHandle());
    queue_ = {};
    for (auto v : m.vertices())
      if (!m.status(v).deleted()) heap_vertex(v);
    size_t nf = m.n_faces(), collapses = 0;
    std::vector<VertexHandle> support;
    while (!queue_.empty() && (target_faces == 0 || nf > target_faces)) {
      Entry e = queue_.top();
      queue_.pop();
      if (e.stamp != stamp_[e.vertex]) continue;  // superseded by a later evaluation
      ++stamp_[e.vertex];
      CollapseInfo ci(m, target_[e.vertex]);
      if (!legal(ci)) continue;  // re-evaluated when a neighbour changes
      support.clear();
      for (auto w : m.vv_range(ci.v0)) support.push_back(w);
      nf -= (m.is_boundary(ci.v0v1) || m.is_boundary(ci.v1v0)) ? 1 : 2;
      this->preprocess_collapse(ci);
      m.collapse(ci.v0v1);
      this->postprocess_collapse(ci);
      ++collapses;
      for (auto w : support) heap_vertex(w);
    }
    return collapses;
  }

 private:
  struct Entry {
    float priority;
    int vertex;
    uint32_t stamp;
    bool operator<(const Entry& o) const { return priority > o.priority; }  // min-heap
  };

  // The vertex's cheapest legal collapse goes on the heap (older entries become stale).
  void heap_vertex(VertexHandle v) {
    MeshT& m = Base::mesh();
    uint32_t st = ++stamp_[v.idx()];
    if (m.status(v).locked()) return;
    float best = FLT_MAX;
    HalfedgeHandle best_h;
    for (auto h : m.voh_range(v)) {
      CollapseInfo ci(m, h);
      if (!legal(ci)) continue;
      float p = this->collapse_priority(ci);
      if (p >= 0.0f && p < best) {
        best = p;
        best_h = h;
      }
    }
    if (!best_h.is_valid()) return;
    target_[v.idx()] = best_h;
    queue_.push(Entry{best, v.idx(), st});
  }

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

  std::vector<uint32_t> tag_, stamp_;
  uint32_t tag_counter_ = 0;
  std::vector<HalfedgeHandle> target_;
  std::priority_queue<Entry> queue_;
};

}  // namespace bb::decimate::detail
