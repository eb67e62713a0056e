// OpenMesh decimation modules of bodybuilder (binary rules, added next to ModQuadricT).
//
// ModSkinWeightsT forbids collapsing two vertices whose skin weights differ by more than a
// threshold (L1 distance of the influence distributions). Human-specific: it keeps the vertex
// rings at elbows, knees and wrists, where the weights change fast, so that the decimated
// extremity still bends like the full one.
//
// ModOriginalNormalsT forbids a collapse after which a face would turn more than a given angle
// away from the ORIGINAL normals of its vertices. ModNormalFlippingT only compares with the face's
// current normal, so many small turns can add up to a flip; this rule cannot drift.
#pragma once

#include <OpenMesh/Core/Utils/Property.hh>
#include <OpenMesh/Tools/Decimater/ModBaseT.hh>

#include <array>
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
class ModOriginalNormalsT : public OpenMesh::Decimater::ModBaseT<MeshT> {
 public:
  DECIMATING_MODULE(ModOriginalNormalsT, MeshT, OriginalNormals);

  explicit ModOriginalNormalsT(MeshT& mesh) : Base(mesh, true) {}

  void set_property(OpenMesh::VPropHandleT<typename MeshT::Normal> p) { prop_ = p; }
  void set_max_deviation_deg(double deg) { min_cos_ = std::cos(deg * 3.14159265358979 / 180.0); }

  float collapse_priority(const CollapseInfo& ci) override {
    MeshT& m = Base::mesh();
    m.set_point(ci.v0, ci.p1);
    bool ok = true;
    for (auto fh : m.vf_range(ci.v0)) {
      if (fh == ci.fl || fh == ci.fr) continue;
      auto n = m.calc_face_normal(fh);
      for (auto v : m.fv_range(fh)) {
        auto vv = v == ci.v0 ? ci.v1 : v;
        if (OpenMesh::dot(n, m.property(prop_, vv)) < min_cos_) { ok = false; break; }
      }
      if (!ok) break;
    }
    m.set_point(ci.v0, ci.p0);
    return ok ? float(Base::LEGAL_COLLAPSE) : float(Base::ILLEGAL_COLLAPSE);
  }

 private:
  OpenMesh::VPropHandleT<typename MeshT::Normal> prop_;
  double min_cos_ = 0.0;
};

}  // namespace bb::decimate::detail
