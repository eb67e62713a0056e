// The only translation unit that includes OpenMesh.
#include "bb/decimate/decimate.h"

#include <chrono>

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>

#include "modules.h"

namespace bb::decimate {

namespace {

struct Traits : OpenMesh::DefaultTraits {
  using Point = OpenMesh::Vec3d;  // double precision quadrics
  using Normal = OpenMesh::Vec3d;
  VertexAttributes(OpenMesh::Attributes::Status);
  FaceAttributes(OpenMesh::Attributes::Status);
  EdgeAttributes(OpenMesh::Attributes::Status);
  HalfedgeAttributes(OpenMesh::Attributes::Status | OpenMesh::Attributes::PrevHalfedge);
};
using Mesh = OpenMesh::TriMesh_ArrayKernelT<Traits>;

// The mesh's live vertices and faces as a SkinnedMesh: each vertex the input vertex `source`
// names, with all its attributes.
mesher::SkinnedMesh to_skinned(const Mesh& mesh, OpenMesh::VPropHandleT<int> source, const mesher::SkinnedMesh& in) {
  const size_t nv = in.positions.size();
  const bool skinned = in.joints.size() == nv && in.weights.size() == nv;
  mesher::SkinnedMesh out;
  std::vector<uint32_t> remap(mesh.n_vertices());
  for (auto v : mesh.vertices()) {
    if (mesh.status(v).deleted()) continue;
    int s = mesh.property(source, v);
    remap[v.idx()] = static_cast<uint32_t>(out.positions.size());
    out.positions.push_back(in.positions[s]);  // halfedge collapses never move survivors
    if (in.normals.size() == nv) out.normals.push_back(in.normals[s]);
    if (in.uvs.size() == nv) out.uvs.push_back(in.uvs[s]);
    if (in.part.size() == nv) out.part.push_back(in.part[s]);
    if (in.seam.size() == nv) out.seam.push_back(in.seam[s]);
    if (skinned) {
      out.joints.push_back(in.joints[s]);
      out.weights.push_back(in.weights[s]);
    }
  }
  for (auto f : mesh.faces()) {
    if (mesh.status(f).deleted()) continue;
    auto fv = mesh.cfv_iter(f);
    for (int k = 0; k < 3; ++k, ++fv) out.indices.push_back(remap[fv->idx()]);
  }
  return out;
}

}  // namespace

Result<mesher::SkinnedMesh> decimate(const mesher::SkinnedMesh& in, const Options& opt, Report* report,
                                     mesher::SkinnedMesh* snapshot) {
  const size_t nv = in.positions.size();
  if (in.indices.size() % 3 != 0) return Error{"", "indices", "index count is not a multiple of 3"};
  if (!opt.locked.empty() && opt.locked.size() != nv)
    return Error{"", "locked", "one flag per vertex expected"};
  bool skinned = in.joints.size() == nv && in.weights.size() == nv;

  Mesh mesh;
  std::vector<Mesh::VertexHandle> vh(nv);
  for (size_t i = 0; i < nv; ++i) {
    const glm::vec3& p = in.positions[i];
    vh[i] = mesh.add_vertex(Mesh::Point(p.x, p.y, p.z));
  }
  OpenMesh::VPropHandleT<int> source;
  OpenMesh::VPropHandleT<detail::Influences> influences;
  mesh.add_property(source);
  mesh.add_property(influences);
  for (size_t i = 0; i < nv; ++i) {
    mesh.property(source, vh[i]) = static_cast<int>(i);
    detail::Influences inf{};
    if (skinned)
      for (int k = 0; k < 4; ++k) inf[k] = {in.joints[i][k], in.weights[i][k]};
    mesh.property(influences, vh[i]) = inf;
  }
  for (size_t t = 0; t < in.indices.size(); t += 3) {
    uint32_t a = in.indices[t], b = in.indices[t + 1], c = in.indices[t + 2];
    if (a >= nv || b >= nv || c >= nv)
      return Error{"", "triangle " + std::to_string(t / 3), "vertex index out of range"};
    if (!mesh.add_face(vh[a], vh[b], vh[c]).is_valid())
      return Error{"", "triangle " + std::to_string(t / 3), "non-manifold or degenerate face, cannot decimate"};
  }
  size_t locked = 0;
  for (size_t i = 0; i < opt.locked.size(); ++i)
    if (opt.locked[i]) { mesh.status(vh[i]).set_locked(true); ++locked; }
  // Original vertex normals: given, or area-weighted from the input faces.
  OpenMesh::VPropHandleT<Mesh::Normal> original_normal;
  mesh.add_property(original_normal);
  {
    std::vector<glm::vec3> n(nv, glm::vec3(0));
    if (in.normals.size() == nv) {
      n = in.normals;
    } else {
      for (size_t t = 0; t < in.indices.size(); t += 3) {
        const auto& a = in.positions[in.indices[t]];
        glm::vec3 fn = glm::cross(in.positions[in.indices[t + 1]] - a, in.positions[in.indices[t + 2]] - a);
        for (int k = 0; k < 3; ++k) n[in.indices[t + k]] += fn;
      }
    }
    for (size_t i = 0; i < nv; ++i) {
      glm::vec3 u = glm::length(n[i]) > 0 ? glm::normalize(n[i]) : glm::vec3(0);
      mesh.property(original_normal, vh[i]) = Mesh::Normal(u.x, u.y, u.z);
    }
  }

  auto t0 = std::chrono::steady_clock::now();
  {
    detail::FastDecimaterT<Mesh> dec(mesh);
    detail::ModQuadricNormalizedT<Mesh>::Handle quadric;
    detail::ModSkinWeightsT<Mesh>::Handle weights;
    dec.add(quadric);
    dec.module(quadric).set_original_normals(original_normal);
    dec.module(quadric).set_max_original_deviation_deg(opt.max_original_normal_deviation_deg);
    dec.module(quadric).set_max_flip_deg(opt.max_normal_deviation_deg);
    dec.module(quadric).set_member_k(opt.member_k);
    if (opt.max_error_m > 0) dec.module(quadric).set_max_error(opt.max_error_m);
    if (skinned && opt.max_weight_difference < 2.0f) {
      dec.add(weights);
      dec.module(weights).set_property(influences);
      dec.module(weights).set_max_difference(opt.max_weight_difference);
    }
    if (!dec.initialize()) return Error{"", "", "OpenMesh decimater failed to initialize"};
    // The snapshot: the mesh after the first pass that leaves at most snapshot_triangles (the
    // passes themselves are the same with or without it).
    bool taken = false;
    if (snapshot && in.indices.size() / 3 <= opt.snapshot_triangles) {
      *snapshot = in;
      taken = true;
    }
    dec.decimate_in_passes(opt.target_triangles, dec.module(quadric), [&](size_t faces) {
      if (snapshot && !taken && faces <= opt.snapshot_triangles) {
        *snapshot = to_skinned(mesh, source, in);
        taken = true;
      }
    });
    {
      // Each survivor may take the place of one of the input vertices it absorbed (position and
      // every attribute), the one nearest to the planes it stands for.
      const bool rule = skinned && opt.max_weight_difference < 2.0f;
      dec.module(quadric).polish(
          [&](Mesh::VertexHandle v, Mesh::VertexHandle w) {
            return !rule || detail::influence_distance(mesh.property(influences, v), mesh.property(influences, w)) <=
                                opt.max_weight_difference;
          },
          [&](Mesh::VertexHandle v, Mesh::VertexHandle w) {
            mesh.property(source, v) = mesh.property(source, w);
          });
    }
  }
  mesh.garbage_collection();
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  mesher::SkinnedMesh out = to_skinned(mesh, source, in);
  if (report) {
    report->triangles_before = in.indices.size() / 3;
    report->triangles_after = out.indices.size() / 3;
    report->vertices_after = out.positions.size();
    report->locked_vertices = locked;
    report->seconds = seconds;
    Distance d = mesh_distance(in.positions, in.indices, out.positions, out.indices);
    report->hausdorff_m = d.hausdorff_m;
    report->mean_m = d.mean_m;
  }
  return out;
}

}  // namespace bb::decimate
