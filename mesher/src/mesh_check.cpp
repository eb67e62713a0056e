// CGAL-backed mesh checks: self-intersections (box_intersection_d + exact triangle predicates),
// distances (AABB tree). Topology (borders, non-manifold edges/vertices, orientation) is counted
// directly on the index buffer. This is the only translation unit that includes CGAL.
#include "bb/mesher/mesh_check.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <unordered_map>
#include <vector>

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/box_intersection_d.h>
#include <CGAL/intersections.h>

namespace bb::mesher {

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = K::Point_3;
using Triangle = K::Triangle_3;
using Segment = K::Segment_3;
using Box = CGAL::Box_intersection_d::Box_with_handle_d<double, 3, size_t,
                                                       CGAL::Box_intersection_d::ID_EXPLICIT>;
using Primitive = CGAL::AABB_triangle_primitive<K, std::vector<Triangle>::const_iterator>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;

Point to_point(const glm::vec3& p) { return Point(p.x, p.y, p.z); }

uint64_t edge_key(uint32_t a, uint32_t b) { return (uint64_t(a) << 32) | b; }

// Two triangles that share vertices intersect elsewhere? (CGAL PMP's rules for adjacent faces.)
bool adjacent_intersect(const Point t1[3], const Point t2[3], const uint32_t i1[3], const uint32_t i2[3]) {
  int shared = 0, s1[3], s2[3];
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b)
      if (i1[a] == i2[b]) { s1[shared] = a; s2[shared] = b; ++shared; }
  if (shared == 0) return CGAL::do_intersect(Triangle(t1[0], t1[1], t1[2]), Triangle(t2[0], t2[1], t2[2]));
  if (shared >= 3) return true;  // duplicate triangle
  if (shared == 2) {
    // Sharing an edge: they overlap only when coplanar and on the same side of the edge.
    int o1 = 3 - s1[0] - s1[1], o2 = 3 - s2[0] - s2[1];
    const Point& p = t1[s1[0]]; const Point& q = t1[s1[1]];
    if (CGAL::orientation(p, q, t1[o1], t2[o2]) != CGAL::COPLANAR) return false;
    return CGAL::coplanar_orientation(p, q, t1[o1], t2[o2]) == CGAL::POSITIVE;
  }
  // Sharing one vertex: the opposite edge of either must not meet the other triangle.
  int a = s1[0], b = s2[0];
  Segment e1(t1[(a + 1) % 3], t1[(a + 2) % 3]);
  Segment e2(t2[(b + 1) % 3], t2[(b + 2) % 3]);
  Triangle T1(t1[0], t1[1], t1[2]), T2(t2[0], t2[1], t2[2]);
  if (CGAL::do_intersect(e1, T2) || CGAL::do_intersect(e2, T1)) return true;
  // Coplanar triangles overlapping around the shared vertex.
  const Point& v = t1[a];
  if (CGAL::orientation(t1[0], t1[1], t1[2], t2[(b + 1) % 3]) == CGAL::COPLANAR &&
      CGAL::orientation(t1[0], t1[1], t1[2], t2[(b + 2) % 3]) == CGAL::COPLANAR) {
    // Both are fans around v in one plane: overlap if an edge of one lies inside the other's angle.
    auto inside = [&](const Point& p, const Point& q, const Point& r) {  // r strictly inside angle pvq
      return CGAL::coplanar_orientation(v, p, r) == CGAL::coplanar_orientation(v, p, q) &&
             CGAL::coplanar_orientation(v, q, r) == CGAL::coplanar_orientation(v, q, p) &&
             CGAL::coplanar_orientation(v, p, r) != CGAL::COLLINEAR;
    };
    const Point &p1 = t1[(a + 1) % 3], &q1 = t1[(a + 2) % 3], &p2 = t2[(b + 1) % 3], &q2 = t2[(b + 2) % 3];
    if (inside(p1, q1, p2) || inside(p1, q1, q2) || inside(p2, q2, p1) || inside(p2, q2, q1)) return true;
  }
  return false;
}

}  // namespace

MeshCheck check_mesh(std::span<const glm::vec3> positions, std::span<const uint32_t> indices,
                     bool find_self_intersections) {
  MeshCheck r;
  const size_t nt = indices.size() / 3, nv = positions.size();
  if (nt == 0) return r;
  // Directed edges -> count; undirected edges -> triangle count.
  std::unordered_map<uint64_t, int> directed, undirected;
  directed.reserve(nt * 4);
  undirected.reserve(nt * 4);
  bool bad_index = false;
  for (size_t t = 0; t < nt; ++t) {
    const uint32_t* v = &indices[3 * t];
    if (v[0] >= nv || v[1] >= nv || v[2] >= nv) { bad_index = true; continue; }
    if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) { ++r.degenerate_triangles; continue; }
    glm::dvec3 a(positions[v[0]]), b(positions[v[1]]), c(positions[v[2]]);
    glm::dvec3 n = glm::cross(b - a, c - a);
    double area = 0.5 * glm::length(n);
    if (!(area > 0)) ++r.degenerate_triangles;
    r.area_m2 += area;
    r.volume_m3 += glm::dot(a, glm::cross(b, c)) / 6.0;
    for (int e = 0; e < 3; ++e) {
      uint32_t p = v[e], q = v[(e + 1) % 3];
      ++directed[edge_key(p, q)];
      ++undirected[edge_key(std::min(p, q), std::max(p, q))];
    }
  }
  bool orientation_ok = true;
  for (const auto& [k, n] : undirected) {
    if (n == 1) ++r.border_edges;
    else if (n > 2) ++r.non_manifold_edges;
    uint32_t a = uint32_t(k >> 32), b = uint32_t(k & 0xffffffffu);
    if (n == 2 && (directed[edge_key(a, b)] != 1 || directed[edge_key(b, a)] != 1)) orientation_ok = false;
  }
  // Non-manifold vertices: the triangles around a vertex must form one fan (connected through
  // shared edges). Union-find over the corners of each vertex.
  {
    std::vector<std::vector<std::pair<uint32_t, uint32_t>>> fans(nv);  // (prev, next) around v
    for (size_t t = 0; t < nt; ++t) {
      const uint32_t* v = &indices[3 * t];
      if (bad_index || v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) continue;
      for (int e = 0; e < 3; ++e) fans[v[e]].push_back({v[(e + 1) % 3], v[(e + 2) % 3]});
    }
    std::vector<int> parent;
    for (size_t i = 0; i < nv; ++i) {
      auto& f = fans[i];
      if (f.empty()) continue;
      parent.resize(f.size());
      for (size_t k = 0; k < f.size(); ++k) parent[k] = int(k);
      auto find = [&](int x) { while (parent[x] != x) x = parent[x] = parent[parent[x]]; return x; };
      std::unordered_map<uint32_t, int> seen;
      for (size_t k = 0; k < f.size(); ++k)
        for (uint32_t w : {f[k].first, f[k].second}) {
          auto [it, fresh] = seen.emplace(w, int(k));
          if (!fresh) parent[find(int(k))] = find(it->second);
        }
      int roots = 0;
      for (size_t k = 0; k < f.size(); ++k) roots += find(int(k)) == int(k);
      if (roots > 1) ++r.non_manifold_vertices;
    }
  }
  // Connected components over triangles sharing vertices.
  {
    std::vector<int> parent(nv);
    for (size_t i = 0; i < nv; ++i) parent[i] = int(i);
    auto find = [&](int x) { while (parent[x] != x) x = parent[x] = parent[parent[x]]; return x; };
    std::vector<char> used(nv, 0);
    for (size_t t = 0; t < nt && !bad_index; ++t) {
      const uint32_t* v = &indices[3 * t];
      used[v[0]] = used[v[1]] = used[v[2]] = 1;
      parent[find(int(v[1]))] = find(int(v[0]));
      parent[find(int(v[2]))] = find(int(v[0]));
    }
    for (size_t i = 0; i < nv; ++i) r.connected_components += used[i] && find(int(i)) == int(i);
  }
  r.closed = !bad_index && r.border_edges == 0 && r.non_manifold_edges == 0;
  r.manifold = !bad_index && r.non_manifold_edges == 0 && r.non_manifold_vertices == 0 &&
               r.degenerate_triangles == 0;
  r.oriented = r.manifold && orientation_ok && (!r.closed || r.volume_m3 > 0);

  if (find_self_intersections && !bad_index) {
    std::vector<Box> boxes;
    boxes.reserve(nt);
    std::vector<std::array<Point, 3>> tris(nt);
    for (size_t t = 0; t < nt; ++t) {
      for (int k = 0; k < 3; ++k) tris[t][k] = to_point(positions[indices[3 * t + k]]);
      boxes.emplace_back(tris[t][0].bbox() + tris[t][1].bbox() + tris[t][2].bbox(), t);
    }
    size_t count = 0;
    auto callback = [&](const Box& a, const Box& b) {
      size_t i = a.handle(), j = b.handle();
      if (adjacent_intersect(tris[i].data(), tris[j].data(), &indices[3 * i], &indices[3 * j])) {
        ++count;
        if (r.intersecting.size() < 64) r.intersecting.push_back({uint32_t(i), uint32_t(j)});
      }
    };
    CGAL::box_self_intersection_d(boxes.begin(), boxes.end(), callback);
    r.self_intersections = count;
  }
  return r;
}

std::vector<uint32_t> intersecting_triangles(std::span<const glm::vec3> positions, std::span<const uint32_t> indices,
                                             std::span<const uint32_t> subset) {
  const size_t nt = indices.size() / 3;
  std::vector<uint32_t> out;
  if (subset.empty() || nt == 0) return out;
  // Only triangles in the grid cells that the subset's boxes touch can meet the subset.
  auto box_of = [&](size_t t, glm::vec3* lo, glm::vec3* hi) {
    glm::vec3 a = positions[indices[3 * t]], b = positions[indices[3 * t + 1]], c = positions[indices[3 * t + 2]];
    *lo = glm::min(a, glm::min(b, c));
    *hi = glm::max(a, glm::max(b, c));
  };
  const float cell = 0.02f;
  auto cells = [&](const glm::vec3& lo, const glm::vec3& hi, auto&& fn) {
    glm::ivec3 a(glm::floor(lo / cell)), b(glm::floor(hi / cell));
    for (int x = a.x; x <= b.x; ++x)
      for (int y = a.y; y <= b.y; ++y)
        for (int z = a.z; z <= b.z; ++z)
          if (fn((uint64_t(uint32_t(x) & 0x1FFFFF) << 42) | (uint64_t(uint32_t(y) & 0x1FFFFF) << 21) |
                 uint64_t(uint32_t(z) & 0x1FFFFF)))
            return;
  };
  std::unordered_map<uint64_t, char> occupied;
  glm::vec3 all_lo(std::numeric_limits<float>::max()), all_hi(-std::numeric_limits<float>::max());
  for (uint32_t t : subset) {
    glm::vec3 lo, hi;
    box_of(t, &lo, &hi);
    all_lo = glm::min(all_lo, lo), all_hi = glm::max(all_hi, hi);
    cells(lo, hi, [&](uint64_t k) { occupied[k] = 1; return false; });
  }
  std::vector<std::array<Point, 3>> tris(nt);
  std::vector<Box> all, some;
  std::vector<int64_t> slot(nt, -1);
  for (size_t t = 0; t < nt; ++t) {
    glm::vec3 lo, hi;
    box_of(t, &lo, &hi);
    if (glm::any(glm::lessThan(hi, all_lo)) || glm::any(glm::greaterThan(lo, all_hi))) continue;
    bool near = false;
    cells(lo, hi, [&](uint64_t k) { return near = occupied.count(k) > 0; });
    if (!near) continue;
    for (int k = 0; k < 3; ++k) tris[t][k] = to_point(positions[indices[3 * t + k]]);
    slot[t] = int64_t(all.size());
    all.emplace_back(tris[t][0].bbox() + tris[t][1].bbox() + tris[t][2].bbox(), t);
  }
  some.reserve(subset.size());
  for (uint32_t t : subset) some.push_back(all[size_t(slot[t])]);
  std::vector<char> hit(nt, 0);
  auto callback = [&](const Box& a, const Box& b) {
    size_t i = a.handle(), j = b.handle();
    if (i == j || (hit[i] && hit[j])) return;
    if (adjacent_intersect(tris[i].data(), tris[j].data(), &indices[3 * i], &indices[3 * j])) hit[i] = hit[j] = 1;
  };
  CGAL::box_intersection_d(some.begin(), some.end(), all.begin(), all.end(), callback);
  for (size_t t = 0; t < nt; ++t)
    if (hit[t]) out.push_back(uint32_t(t));
  return out;
}

namespace {

std::vector<Triangle> triangles_of(std::span<const glm::vec3> p, std::span<const uint32_t> idx) {
  std::vector<Triangle> t;
  t.reserve(idx.size() / 3);
  for (size_t i = 0; i + 2 < idx.size(); i += 3) {
    Triangle tri(to_point(p[idx[i]]), to_point(p[idx[i + 1]]), to_point(p[idx[i + 2]]));
    if (!tri.is_degenerate()) t.push_back(tri);
  }
  return t;
}

// Points spread over the mesh: every vertex plus area-weighted random points.
std::vector<glm::vec3> sample_mesh(std::span<const glm::vec3> p, std::span<const uint32_t> idx, int n) {
  std::vector<glm::vec3> out(p.begin(), p.end());
  size_t nt = idx.size() / 3;
  if (nt == 0 || n <= 0) return out;
  std::vector<double> cum(nt);
  double total = 0;
  for (size_t t = 0; t < nt; ++t) {
    glm::vec3 a = p[idx[3 * t]], b = p[idx[3 * t + 1]], c = p[idx[3 * t + 2]];
    total += 0.5 * glm::length(glm::cross(b - a, c - a));
    cum[t] = total;
  }
  std::mt19937 rng(12345);
  std::uniform_real_distribution<double> u(0, 1);
  for (int i = 0; i < n; ++i) {
    size_t t = std::lower_bound(cum.begin(), cum.end(), u(rng) * total) - cum.begin();
    t = std::min(t, nt - 1);
    double r1 = std::sqrt(u(rng)), r2 = u(rng);
    glm::vec3 a = p[idx[3 * t]], b = p[idx[3 * t + 1]], c = p[idx[3 * t + 2]];
    out.push_back(float(1 - r1) * a + float(r1 * (1 - r2)) * b + float(r1 * r2) * c);
  }
  return out;
}

}  // namespace

void distances_to_mesh(std::span<const glm::vec3> positions, std::span<const uint32_t> indices,
                       std::span<const glm::vec3> points, std::span<double> out) {
  std::vector<Triangle> tris = triangles_of(positions, indices);
  if (tris.empty()) {
    std::fill(out.begin(), out.end(), std::numeric_limits<double>::infinity());
    return;
  }
  Tree tree(tris.begin(), tris.end());
  tree.accelerate_distance_queries();
  for (size_t i = 0; i < points.size(); ++i) out[i] = std::sqrt(tree.squared_distance(to_point(points[i])));
}

double hausdorff_distance(std::span<const glm::vec3> pa, std::span<const uint32_t> ia,
                          std::span<const glm::vec3> pb, std::span<const uint32_t> ib,
                          int samples_per_mesh) {
  if (ia.size() < 3 || ib.size() < 3) return -1;
  double h = 0;
  for (int dir = 0; dir < 2; ++dir) {
    auto sp = dir == 0 ? pa : pb;
    auto si = dir == 0 ? ia : ib;
    auto tp = dir == 0 ? pb : pa;
    auto ti = dir == 0 ? ib : ia;
    std::vector<glm::vec3> pts = sample_mesh(sp, si, samples_per_mesh);
    std::vector<double> d(pts.size());
    distances_to_mesh(tp, ti, pts, d);
    for (double x : d) h = std::max(h, x);
  }
  return h;
}

}  // namespace bb::mesher
