// Section 3.1 of the paper: contours circle each limb link, rays are cast star-shaped from the
// link, the outermost crossing is a sample; one surface sampled at several densities gives
// look-alike levels of detail.
//
// Each level is assembled from five closed pieces: the torso (pelvis to head) and four limbs
// (shoulder to hand, hip to foot). A piece is a chain of rings around its axis (a radial graph,
// so it cannot fold however concave the skin), closed at its start by a cap cast from the first
// ring's centre and at its end by the extremity: either a star-shaped "cup" cast from the centre
// of the hand, foot or head, or the full-resolution OpenVDB mesh cut at the seam plane and
// zipped to the last ring. CGAL corefinement unites the five pieces into one closed 2-manifold.
#include "bb/mesher/mesher.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <numeric>
#include <queue>
#include <random>
#include <span>
#include <thread>
#include <unordered_map>

#include <glm/gtc/constants.hpp>

#include "bb/mesher/mesh_check.h"
#include "bb/modeler/implicit_surface.h"
#include "internal.h"

namespace bb::mesher {

using detail::Extremity;
using detail::PieceMesh;
using detail::PlainMesh;
using detail::SubField;

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

thread_local StageTimes g_times;

uint64_t position_key(const glm::vec3& p) {
  uint32_t b[3];
  std::memcpy(b, &p, 12);
  return (uint64_t(b[0]) * 0x9E3779B97F4A7C15ull) ^ (uint64_t(b[1]) * 0xC2B2AE3D27D4EB4Full) ^ b[2];
}

// Skinning regions: which bones a vertex may follow.
enum Region : int8_t { kTorso, kArmL, kArmR, kLegL, kLegR, kHead, kHandL, kHandR, kFootL, kFootR, kRegions };

struct Bone {
  int joint;
  glm::vec3 a, b;  // bind-posture segment, metres
};

// One ring of samples around an axis point.
struct Ring {
  std::vector<uint32_t> ids;   // vertex indices in the piece mesh
  std::vector<float> angles;   // radians around the axis, increasing, in [a0, a0 + 2 pi)
};

struct Frame {
  glm::vec3 c, t, u, v;  // centre, tangent, ring axes (v = t x u)
};

// What one piece needs, independent of the level of detail.
struct PieceSpec {
  std::vector<glm::vec3> axis;  // polyline from the start joint to the seam point
  int links = 2;
  int8_t region = kTorso, ext_region = kHead;
  MeshPart ext_part = MeshPart::kHead;
  std::vector<int> prims;
  glm::vec3 cup_center{0}, cup_pole{0};
  float ext_voxel = 0.004f;
  modeler::Aabb ext_box;
  std::unique_ptr<SubField> field;
  Extremity vdb;          // OpenVDB extremity (when some level needs it)
  Frame seam_frame;       // frame of the seam ring (for zipping angles)
};

float wrap_angle(float a) {
  const float two_pi = glm::two_pi<float>();
  a = std::fmod(a, two_pi);
  return a < 0 ? a + two_pi : a;
}

// Point and smoothed tangent at arc length s along a polyline: the chord over `w` either side.
Frame frame_at(const std::vector<glm::vec3>& axis, float s, float w = 0.06f) {
  auto point = [&](float x) {
    x = std::max(0.0f, x);
    for (size_t i = 0; i + 1 < axis.size(); ++i) {
      float len = glm::distance(axis[i], axis[i + 1]);
      if (x <= len || i + 2 == axis.size()) return axis[i] + (axis[i + 1] - axis[i]) * std::min(1.0f, x / len);
      x -= len;
    }
    return axis.back();
  };
  float total = 0;
  for (size_t i = 0; i + 1 < axis.size(); ++i) total += glm::distance(axis[i], axis[i + 1]);
  Frame f;
  f.c = point(s);
  glm::vec3 a = point(std::max(0.0f, s - w)), b = point(std::min(total, s + w));
  f.t = glm::normalize(b - a);
  return f;
}

float axis_length(const std::vector<glm::vec3>& axis) {
  float total = 0;
  for (size_t i = 0; i + 1 < axis.size(); ++i) total += glm::distance(axis[i], axis[i + 1]);
  return total;
}

// Ring frames along the axis at arc lengths `at` (increasing), parallel-transported u.
std::vector<Frame> ring_frames(const std::vector<glm::vec3>& axis, const std::vector<float>& at,
                               float tangent_window = 0.06f) {
  std::vector<Frame> out;
  const float total = axis_length(axis), base = 0.06f;
  for (float s : at) {
    // A wider window narrows back to the base one towards the seam end: the last ring is zipped
    // to the extremity's seam loop, whose plane is set by the base window.
    const float w = tangent_window > base ? std::min(tangent_window, std::max(base, total - s)) : tangent_window;
    Frame f = frame_at(axis, s, w);
    glm::vec3 u;
    if (out.empty()) {
      // Start with the body's forward (+Z) or, for a forward axis, up (+Y).
      glm::vec3 ref = std::abs(f.t.z) < 0.9f ? glm::vec3(0, 0, 1) : glm::vec3(0, 1, 0);
      u = ref - glm::dot(ref, f.t) * f.t;
    } else {
      u = out.back().u - glm::dot(out.back().u, f.t) * f.t;
    }
    f.u = glm::normalize(u);
    f.v = glm::cross(f.t, f.u);
    out.push_back(f);
  }
  return out;
}

// `rings` evenly spaced arc lengths from 0 to the axis' length.
std::vector<float> even_rings(const std::vector<glm::vec3>& axis, int rings) {
  std::vector<float> at(rings);
  float total = axis_length(axis);
  for (int k = 0; k < rings; ++k) at[k] = total * float(k) / float(rings - 1);
  return at;
}

std::vector<Frame> ring_frames(const std::vector<glm::vec3>& axis, int rings) {
  return ring_frames(axis, even_rings(axis, rings));
}

float sample_ray(const SubField& field, const glm::vec3& o, const glm::vec3& d, float max_t, float fallback) {
  auto t = field.outermost(o, d, max_t);
  return t ? *t : fallback;
}

// The piece's own skin is crossed at t_own; the whole skin may continue beyond it where
// primitives of neighbouring pieces blend in (armpit, shoulder, groin). Follow the ray through
// the whole skin and take its first exit if it comes within `margin`. If the ray is still inside
// the skin there, it has run into the blend with a neighbouring piece: end it at that depth so
// that the piece reaches into the neighbour and the union fills the crease between them (the
// point is inside the skin; the neighbour's piece covers it).
// Only the torso lands on the blend (`land` = true); limbs either keep their own skin or go deep,
// so that no two pieces sample the same stretch of skin (near-coincident surfaces make the
// union's intersection curves degenerate).
thread_local const SubField* g_whole = nullptr;
// Cap rays (the torso's pelvis cap reaches down between the thighs) may go further through the
// blend before they count as deep on levels whose creases are fitted after the union: the groin
// lies farther below the pelvis than the cap's own skin, by up to its own depth on slim
// variants, and the fitting needs the cap there. (Coarser levels keep the shorter reach: a cap
// reaching deep between the thighs follows the pelvis when the legs swing apart.)
thread_local float g_cap_margin = 0.6f;
float extend_to_whole(const glm::vec3& o, const glm::vec3& d, float t_own, float margin, bool land = true) {
  if (!g_whole) return t_own;
  const float h = 0.002f;
  float t = t_own;
  for (float end = t_own + margin; t < end;) {
    float tn = std::min(end, t + h);
    if (g_whole->field(o + tn * d) < modeler::kIso) {
      if (!land) return t_own;
      float a = t, b = tn;
      for (int i = 0; i < 20; ++i) {
        float mid = 0.5f * (a + b);
        if (g_whole->field(o + mid * d) >= modeler::kIso) a = mid; else b = mid;
      }
      return 0.5f * (a + b);
    }
    t = tn;
  }
  return t_own + margin;
}

// Triangles between two rings (b further along the piece): quads when the rings match,
// otherwise a zipper that advances on whichever ring has the smaller next angle.
void strip(const Ring& a, const Ring& b, std::vector<uint32_t>& idx) {
  const size_t n = a.ids.size(), m = b.ids.size();
  if (n == m) {
    for (size_t k = 0; k < n; ++k) {
      size_t k1 = (k + 1) % n;
      idx.insert(idx.end(), {a.ids[k], a.ids[k1], b.ids[k1], a.ids[k], b.ids[k1], b.ids[k]});
    }
    return;
  }
  const float two_pi = glm::two_pi<float>();
  auto ang = [&](const Ring& r, size_t i) { return i < r.angles.size() ? r.angles[i] : r.angles[0] + two_pi; };
  // Align b to start at the vertex nearest a's first angle.
  size_t i = 0, j = 0;
  while (i < n || j < m) {
    bool advance_a = j == m || (i < n && ang(a, i + 1) < ang(b, j + 1));
    if (advance_a) {
      idx.insert(idx.end(), {a.ids[i % n], a.ids[(i + 1) % n], b.ids[j % m]});
      ++i;
    } else {
      idx.insert(idx.end(), {a.ids[i % n], b.ids[(j + 1) % m], b.ids[j % m]});
      ++j;
    }
  }
}

void fan(uint32_t pole, const Ring& r, bool pole_after, std::vector<uint32_t>& idx) {
  const size_t n = r.ids.size();
  for (size_t k = 0; k < n; ++k) {
    size_t k1 = (k + 1) % n;
    if (pole_after) idx.insert(idx.end(), {r.ids[k], r.ids[k1], pole});
    else idx.insert(idx.end(), {pole, r.ids[k1], r.ids[k]});
  }
}

// A ring of `points` samples cast from f.c in the plane of f.
Ring cast_ring(const SubField& field, const Frame& f, int points, PieceMesh& mesh, uint8_t part, uint8_t seam,
               int8_t region, std::vector<float>* radii = nullptr, bool extend = false, bool land = true) {
  Ring r;
  float prev = 0.005f;
  for (int k = 0; k < points; ++k) {
    float th = glm::two_pi<float>() * float(k) / float(points);
    glm::vec3 d = std::cos(th) * f.u + std::sin(th) * f.v;
    float t = sample_ray(field, f.c, d, 1.0f, prev);
    prev = t;
    if (extend) t = extend_to_whole(f.c, d, t, 0.6f * t, land);
    if (radii) radii->push_back(t);
    r.ids.push_back(mesh.add(f.c + t * d, part, seam, region));
    r.angles.push_back(th);
  }
  return r;
}

// Cap of latitude rings cast from f.c, away from the piece (-t when `backwards`).
// Returns rings from the one next to `rim` out to the last, and sets *pole.
std::vector<Ring> cast_cap(const SubField& field, const Frame& f, int points, int lat, bool backwards,
                           PieceMesh& mesh, int8_t region, uint32_t* pole, bool land, bool extend) {
  std::vector<Ring> rings;
  glm::vec3 axis = backwards ? -f.t : f.t;
  for (int j = 1; j < lat; ++j) {
    float phi = glm::half_pi<float>() * float(j) / float(lat);
    Ring r;
    for (int k = 0; k < points; ++k) {
      float th = glm::two_pi<float>() * float(k) / float(points);
      glm::vec3 d = std::cos(phi) * (std::cos(th) * f.u + std::sin(th) * f.v) + std::sin(phi) * axis;
      float t = sample_ray(field, f.c, d, 1.0f, 0.005f);
      if (extend) t = extend_to_whole(f.c, d, t, g_cap_margin * t, land);
      r.ids.push_back(mesh.add(f.c + t * d, uint8_t(MeshPart::kBody), 0, region));
      r.angles.push_back(th);
    }
    rings.push_back(std::move(r));
  }
  float t = sample_ray(field, f.c, axis, 1.0f, 0.005f);
  if (extend) t = extend_to_whole(f.c, axis, t, g_cap_margin * t, land);
  *pole = mesh.add(f.c + t * axis, uint8_t(MeshPart::kBody), 0, region);
  return rings;
}

// Contour-sampled extremity: latitude rings cast from the cup centre, from the directions of
// the rim (the seam ring) to the pole, only beyond the seam plane.
void cast_cup(const SubField& field, const PieceSpec& spec, const Frame& seam, const Ring& rim, int lat,
              int points, PieceMesh& mesh, std::vector<uint32_t>& idx) {
  const glm::vec3 c = spec.cup_center, pole = glm::normalize(spec.cup_pole);
  const uint8_t part = uint8_t(spec.ext_part);
  // Meridians: `points` of them (at least the rim's), starting from the rim polyline at
  // angles 2 pi k / points.
  const size_t n_rim = rim.ids.size(), n = std::max<size_t>(n_rim, size_t(points));
  std::vector<glm::vec3> start(n), d0(n), out(n);
  std::vector<float> angles(n);
  for (size_t k = 0; k < n; ++k) {
    float a = float(k) / float(n) * float(n_rim);
    size_t k0 = size_t(a) % n_rim, k1 = (k0 + 1) % n_rim;
    float f = a - std::floor(a);
    start[k] = (1 - f) * mesh.positions[rim.ids[k0]] + f * mesh.positions[rim.ids[k1]];
    d0[k] = glm::normalize(start[k] - c);
    // The meridian's way down: through the rim point's outward direction (from the limb's axis,
    // square to the pole), so that it sweeps the side of the cup the rim point is on. (Going
    // straight from d0 to the pole is ill-defined when the rim point lies right above the cup
    // centre, as the front of a slim shin can: the meridian then swept the heel, not the toes.)
    glm::vec3 r = start[k] - seam.c;
    r -= glm::dot(r, pole) * pole;
    out[k] = glm::dot(r, r) > 1e-12f ? glm::normalize(r) : d0[k];
    angles[k] = glm::two_pi<float>() * float(k) / float(n);
  }
  auto slerp = [](glm::vec3 a, glm::vec3 b, float s) {
    float cosang = glm::clamp(glm::dot(a, b), -1.0f, 1.0f);
    float ang = std::acos(cosang);
    if (ang < 1e-4f) return a;
    if (ang > glm::pi<float>() - 1e-3f) {  // opposite: go around through an orthogonal direction
      glm::vec3 o = glm::normalize(glm::cross(a, glm::abs(a.x) < 0.9f ? glm::vec3(1, 0, 0) : glm::vec3(0, 1, 0)));
      return glm::normalize(std::cos(ang * s) * a + std::sin(ang * s) * o);
    }
    return glm::normalize((std::sin((1 - s) * ang) * a + std::sin(s * ang) * b) / std::sin(ang));
  };
  auto cast = [&](size_t k, float s) {
    // d0 -> out -> pole, s proportional to the angle travelled.
    float a1 = std::acos(glm::clamp(glm::dot(d0[k], out[k]), -1.0f, 1.0f));
    float a2 = std::acos(glm::clamp(glm::dot(out[k], pole), -1.0f, 1.0f));
    float s1 = a1 + a2 > 0 ? a1 / (a1 + a2) : 0.0f;
    glm::vec3 d = s < s1 ? slerp(d0[k], out[k], s / s1) : slerp(out[k], pole, s1 < 1 ? (s - s1) / (1 - s1) : 1.0f);
    // Only the part of the ray beyond the seam plane counts.
    float dn = glm::dot(d, seam.t), max_t = 1.0f;
    float sc = glm::dot(c - seam.c, seam.t);
    if (dn < -1e-6f) max_t = std::min(max_t, sc / -dn);
    return c + sample_ray(field, c, d, max_t, 0.005f) * d;
  };
  // Latitudes evenly spaced in arc length along each meridian, so that long parts (toes,
  // fingers) get their share of rings whatever the density. Per meridian the rings stay in
  // order (s increases), so the cup remains a radial graph around c and cannot fold.
  const int fine = 48;
  const size_t n_mer = d0.size();
  std::vector<std::vector<double>> arc(n_mer, std::vector<double>(fine + 1, 0.0));
  for (size_t k = 0; k < n_mer; ++k) {
    glm::vec3 prev_p = start[k];
    for (int i = 1; i <= fine; ++i) {
      glm::vec3 p = cast(k, float(i) / fine);
      arc[k][i] = arc[k][i - 1] + glm::distance(p, prev_p);
      prev_p = p;
    }
  }
  auto s_at = [&](size_t k, double frac) {
    const std::vector<double>& a = arc[k];
    double target = frac * a[fine];
    int i = 1;
    while (i < fine && a[i] < target) ++i;
    double a0 = a[i - 1], a1 = a[i];
    double f = a1 > a0 ? (target - a0) / (a1 - a0) : 0.0;
    return float((i - 1 + f) / fine);
  };
  Ring prev = rim;
  for (int j = 1; j < lat; ++j) {
    Ring r;
    for (size_t k = 0; k < n_mer; ++k) {
      r.ids.push_back(mesh.add(cast(k, s_at(k, double(j) / lat)), part, 0, spec.ext_region));
      r.angles.push_back(angles[k]);
    }
    strip(prev, r, idx);
    prev = std::move(r);
  }
  float t = sample_ray(field, c, pole, 1.0f, 0.005f);
  uint32_t p = mesh.add(c + t * pole, part, 0, spec.ext_region);
  fan(p, prev, true, idx);
}

// One closed piece at one density.
// An OpenVDB extremity kept out of the union: its vertices, the seam ring it is zipped to (by
// position, the union keeps those vertices as they are), its triangles (index < ring.size():
// a ring vertex; else ext vertex index - ring.size()) and the pole of the stand-in fan.
struct Attachment {
  std::vector<glm::vec3> ring;
  PieceMesh ext;
  std::vector<uint32_t> tris;
  glm::vec3 pole{0};
};

PieceMesh build_piece(const PieceSpec& spec, const PartDensity& density, int cup_rings, int cup_points, bool vdb,
                      float ring_gap, bool deep_cap, Attachment* att = nullptr, float tangent_window = 0.06f) {
  PieceMesh mesh;
  const SubField& field = *spec.field;
  const int rings = std::max(2, density.contours * spec.links + 1);
  std::vector<glm::vec3> axis = spec.axis;
  if (vdb) {
    // Stop the rings `ring_gap` short of the seam plane; the zipper spans the gap.
    glm::vec3 dir = glm::normalize(axis.back() - axis[axis.size() - 2]);
    axis.back() -= ring_gap * dir;
  }
  std::vector<uint32_t>& idx = mesh.indices;
  // Start cap.
  uint32_t pole = 0;
  const bool land = spec.region == kTorso;
  // Legs keep their own skin: the two thighs going deep into each other meet in mirrored,
  // nearly coincident triangles at the body's midplane, which the union cannot round safely.
  const bool extend = spec.region != kLegL && spec.region != kLegR;
  std::vector<float> at = even_rings(axis, rings);
  std::vector<Frame> frames = ring_frames(axis, at, tangent_window);
  const int ring_count = int(frames.size());
  Ring first = cast_ring(field, frames[0], density.points, mesh, uint8_t(MeshPart::kBody), 0, spec.region, nullptr,
                         extend, land);
  g_cap_margin = deep_cap ? 1.0f : 0.6f;
  std::vector<Ring> cap = cast_cap(field, frames[0], density.points, std::max(2, density.points / 4), true, mesh,
                                   spec.region, &pole, land, extend);
  // Cap rings go from the equator (next to `first`) to the pole; seen along the piece they come
  // before `first`, pole first.
  {
    const Ring* prev = nullptr;
    for (int j = int(cap.size()) - 1; j >= 0; --j) {
      if (!prev) fan(pole, cap[j], false, idx);
      else strip(*prev, cap[j], idx);
      prev = &cap[j];
    }
    if (prev) strip(*prev, first, idx);
    else fan(pole, first, false, idx);
  }
  Ring prev = std::move(first);
  for (int k = 1; k < ring_count; ++k) {
    bool last = k == ring_count - 1;
    // The last ring (at the seam) keeps the piece's own skin: the extremity is meshed from it.
    Ring r = cast_ring(field, frames[k], density.points, mesh, uint8_t(MeshPart::kBody), last ? 1 : 0, spec.region,
                       nullptr, !last && extend, land);
    strip(prev, r, idx);
    prev = std::move(r);
  }
  if (!vdb) {
    cast_cup(field, spec, frames.back(), prev, cup_rings, cup_points, mesh, idx);
    return mesh;
  }
  // Zip the last ring to the OpenVDB extremity's border loop.
  const Frame& sf = spec.seam_frame;
  const Frame& lf = frames.back();
  // Re-express the last ring's angles in the seam frame (same axis direction up to the smoothing).
  for (size_t k = 0; k < prev.ids.size(); ++k) {
    glm::vec3 d = mesh.positions[prev.ids[k]] - lf.c;
    prev.angles[k] = std::atan2(glm::dot(d, sf.v), glm::dot(d, sf.u));
  }
  uint32_t base = uint32_t(mesh.positions.size());
  const size_t tri_start = idx.size();
  for (size_t i = 0; i < spec.vdb.positions.size(); ++i)
    mesh.add(spec.vdb.positions[i], uint8_t(spec.ext_part), 0, spec.ext_region);
  for (uint32_t i : spec.vdb.indices) idx.push_back(base + i);
  Ring loop;
  for (uint32_t v : spec.vdb.loop) {
    mesh.seam[base + v] = 1;
    loop.ids.push_back(base + v);
    glm::vec3 d = spec.vdb.positions[v] - sf.c;
    loop.angles.push_back(std::atan2(glm::dot(d, sf.v), glm::dot(d, sf.u)));
  }
  // Both rings: start at the smallest angle, unwrap to increasing.
  auto normalize_ring = [](Ring& r) {
    size_t n = r.ids.size();
    size_t start = 0;
    for (size_t i = 1; i < n; ++i)
      if (wrap_angle(r.angles[i]) < wrap_angle(r.angles[start])) start = i;
    Ring o;
    float a0 = wrap_angle(r.angles[start]), acc = a0;
    for (size_t k = 0; k < n; ++k) {
      size_t i = (start + k) % n;
      if (k > 0) {
        float d = r.angles[i] - r.angles[(start + k - 1) % n];
        d = std::remainder(d, glm::two_pi<float>());
        acc += d;
      }
      o.ids.push_back(r.ids[i]);
      o.angles.push_back(acc);
    }
    r = std::move(o);
  };
  normalize_ring(prev);
  normalize_ring(loop);
  strip(prev, loop, idx);
  if (!att) return mesh;
  // Hand the extremity and its zipper to `att`; close the piece with a fan to the seam centre
  // instead, which is all the union needs to see there.
  att->ring.clear();
  std::unordered_map<uint32_t, uint32_t> ring_slot;
  for (uint32_t id : prev.ids) {
    ring_slot[id] = uint32_t(att->ring.size());
    att->ring.push_back(mesh.positions[id]);
  }
  const uint32_t R = uint32_t(att->ring.size());
  att->ext = PieceMesh{};
  for (uint32_t v = base; v < mesh.positions.size(); ++v)
    att->ext.add(mesh.positions[v], mesh.part[v], mesh.seam[v], mesh.region[v]);
  att->tris.clear();
  for (size_t i = tri_start; i < idx.size(); ++i) {
    uint32_t v = idx[i];
    att->tris.push_back(v >= base ? R + (v - base) : ring_slot.at(v));
  }
  idx.resize(tri_start);
  mesh.positions.resize(base);
  mesh.part.resize(base);
  mesh.seam.resize(base);
  mesh.region.resize(base);
  att->pole = sf.c;
  uint32_t pole_id = mesh.add(sf.c, uint8_t(MeshPart::kBody), 0, spec.region);
  Ring ring_in_order;
  ring_in_order.ids = prev.ids;
  fan(pole_id, ring_in_order, true, idx);
  return mesh;
}

// At most four influences, continuous in the candidates' weights: the four strongest less the
// fifth's weight, so a joint fades out as it drops to fifth place. Cut to four outright, the
// weights jumped where the 4th and 5th swap: on a belly edited to 0.3 m five joints (two hips,
// three vertebrae) weigh 0.13-0.3 each, neighbouring vertices kept different fours, and in a
// stride the belly folded along that line, a dark sliver
// (Skinning.HugeBellyDoesNotFoldWhenTheHipsSwing). `w`: weights, descending; returns how many
// to keep (at most 4, the first ones), lowered in place. A 4th tied with the 5th comes out 0.
size_t keep_four(std::span<float> w) {
  if (w.size() > 4 && w[0] > w[4])
    for (size_t k = 0; k < 4; ++k) w[k] -= w[4];
  return std::min<size_t>(4, w.size());
}

// A vertex's influences from candidate (weight, joint) pairs, strongest first: at most four
// (keep_four), those at 0 or under `floor` of their sum dropped, normalized to a sum of exactly one
// in float.
void store_influences(std::vector<std::pair<float, int>>& w, float floor, glm::u16vec4* joints, glm::vec4* weights) {
  std::vector<float> x(w.size());
  for (size_t k = 0; k < w.size(); ++k) x[k] = w[k].first;
  w.resize(keep_four(x));
  float sum = 0;
  for (size_t k = 0; k < w.size(); ++k) sum += (w[k].first = x[k]);
  while (!w.empty() && (w.back().first <= 0 || w.back().first < floor * sum)) w.pop_back();  // the weakest last
  float kept = 0;
  for (const auto& q : w) kept += q.first;
  for (size_t k = 0; k < 4; ++k) {
    (*joints)[k] = uint16_t(k < w.size() ? w[k].second : 0);
    (*weights)[k] = k < w.size() ? w[k].first / kept : 0.0f;
  }
  const float s = (*weights)[0] + (*weights)[1] + (*weights)[2] + (*weights)[3];
  (*weights)[0] += 1.0f - s;
}

// Skin weights: inverse fourth power of the distance to the region's bones, at most four
// (keep_four), normalized; smooth across joints because neighbouring bones are equally near there.
void skin_vertex(const glm::vec3& p, const std::vector<Bone>& bones, const std::vector<int>& candidates,
                 glm::u16vec4* joints, glm::vec4* weights) {
  struct W { float w; int joint; };
  W best[5] = {{0, 0}, {0, 0}, {0, 0}, {0, 0}, {0, 0}};
  std::unordered_map<int, float> per_joint;
  for (int b : candidates) {
    const Bone& bone = bones[b];
    glm::vec3 ab = bone.b - bone.a;
    float len2 = glm::dot(ab, ab);
    float t = len2 > 0 ? glm::clamp(glm::dot(p - bone.a, ab) / len2, 0.0f, 1.0f) : 0.0f;
    glm::vec3 dp = p - (bone.a + t * ab);
    float d2 = glm::dot(dp, dp) + 1e-6f;
    float w = 1.0f / (d2 * d2);
    float& pj = per_joint[bone.joint];
    pj = std::max(pj, w);
  }
  for (const auto& [j, w] : per_joint) {
    W cand{w, j};
    for (int k = 0; k < 5; ++k)
      if (cand.w > best[k].w) std::swap(cand, best[k]);
  }
  std::vector<std::pair<float, int>> w;
  for (const W& b : best) w.push_back({b.w, b.joint});
  store_influences(w, 0.01f, joints, weights);  // influences under 1 % dropped
}

// Half width of the band over which skin weights ramp across a seam between the torso and an arm
// (metres along the mesh's edges, for a body 1.75 m tall). Measured on the default body's walk
// (the shoulders' triangles turned over and in sight from 16 directions, every frame, LOD 0):
// 73,524 pixel-views before, about 1,500 with 4-6 cm, 761 with 10 cm (LOD 1-2 gain most from the
// wider band); a band of 1.5-3 arm ring spacings (up to 27 cm at LOD 3) made LOD 3 6x worse.
constexpr float kSeamBlend = 0.10f;
// The shortest edge length the seam ramp's weights count (metres): coincident vertices still pull
// each other finitely.
constexpr float kShortestEdge = 0.002f;
// Successive over-relaxation of the seam ramp's Gauss-Seidel sweeps: the same weights (to the one
// pixel in sight of Skinning.ShouldersDoNotFoldWhenTheArmsHang) in 2,607 sweeps instead of 18,558
// over the skinning tests' levels (LOD 0 of the default body: 111 instead of 1,113).
constexpr float kOverRelaxation = 1.8f;

// Each piece's vertices weigh only their own region's bones, so where the union joins a limb to
// the torso the weights jumped: at the top of the shoulder a torso vertex all sternoclavicular,
// the arm's vertex 0.3 mm away three quarters shoulder. In the walk the arm hangs 36 deg below the
// bind posture's 45, the two sides parted and the skin folded between them: dark triangles at the
// front of the armpits and a stepped outline over the shoulders
// (Skinning.ShouldersDoNotFoldWhenTheArmsHang); between the thighs likewise. Within `band`
// (metres along the edges) of such a seam (below; `region` -1: a vertex the union or the crease
// fitting made) the weights become the harmonic interpolation of those at the band's edge
// (Gauss-Seidel, over-relaxed), so they ramp across the seam; then at most four (keep_four), normalized. Each
// edge weighs 1 / its length (at most 1 / kShortestEdge), so the ramp is even in metres: with
// every edge alike it was even in edges, and the union's seams, strips of triangles a few
// millimetres wide, took much of the ramp within a centimetre (at the back of the armpits 0.3 of
// shoulder weight in 1 cm, which folded over when the arms came down). Area turned over, measured:
// the groin in a stride, LOD 0-3, 10.5 / 13.4 / 1.2 / 11.2 cm2 -> 2.3 / 2.5 / 0.1 / 0.4; the
// shoulders' in sight over the default body and seeded variants 1-3 (each with its walk's arms,
// bb/modeler/clearance.h) 44.6 -> 18.5 cm2.
void smooth_seam_weights(SkinnedMesh& mesh, const std::vector<int8_t>& region, float band) {
  const size_t nv = mesh.positions.size();
  std::vector<std::vector<uint32_t>> nbr(nv);
  for (size_t t = 0; t < mesh.indices.size(); t += 3)
    for (int e = 0; e < 3; ++e) {
      uint32_t a = mesh.indices[t + e], b = mesh.indices[t + (e + 1) % 3];
      nbr[a].push_back(b);
      nbr[b].push_back(a);
    }
  for (auto& n : nbr) {
    std::sort(n.begin(), n.end());
    n.erase(std::unique(n.begin(), n.end()), n.end());
  }
  // A made vertex (region -1) belongs to the limb whose vertex is nearest along the edges.
  std::vector<float> dist(nv, std::numeric_limits<float>::infinity());
  std::vector<int8_t> limb(nv, -1);
  using Item = std::pair<float, uint32_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> queue;
  auto spread = [&](float reach) {
    while (!queue.empty()) {
      auto [d, i] = queue.top();
      queue.pop();
      if (d > dist[i] || d >= reach) continue;
      for (uint32_t j : nbr[i]) {
        float dj = d + glm::distance(mesh.positions[i], mesh.positions[j]);
        if (dj < dist[j]) dist[j] = dj, limb[j] = limb[i], queue.push({dj, j});
      }
    }
  };
  for (size_t i = 0; i < nv; ++i)
    if (region[i] >= kArmL && region[i] <= kLegR) dist[i] = 0, limb[i] = region[i], queue.push({0.0f, uint32_t(i)});
  spread(std::numeric_limits<float>::infinity());
  // Seams between the torso and a limb: a made vertex of a limb, a torso vertex next to a limb's
  // and the other way (vertices merely next to a made one are not: on the coarsest level that
  // would free a whole ring 18 cm from the seam). The legs' too since the crease fitting's vertices
  // are skinned by their region: before, a belly edited to 0.3 m folded where its underside ramped
  // to the thighs (Skinning.HugeBellyDoesNotFoldWhenTheHipsSwing); now the groin folds half as much
  // in a stride (Skinning.GroinDoesNotFoldInAStride).
  auto arm = [](int r) { return r == kArmL || r == kArmR || r == kLegL || r == kLegR; };
  std::fill(dist.begin(), dist.end(), std::numeric_limits<float>::infinity());
  for (size_t i = 0; i < nv; ++i) {
    bool seam = region[i] < 0 && arm(limb[i]);
    for (uint32_t j : nbr[i]) seam |= (region[i] == kTorso && arm(region[j])) || (arm(region[i]) && region[j] == kTorso);
    if (seam && mesh.part[i] == 0) dist[i] = 0, queue.push({0.0f, uint32_t(i)});
  }
  if (queue.empty()) return;
  spread(band);
  // The band's vertices (extremities and seams kept as they are) and the joints involved.
  std::vector<uint32_t> free;
  std::vector<int> slot;  // joint -> column
  std::vector<uint16_t> columns;
  auto column = [&](uint16_t j) {
    if (j >= slot.size()) slot.resize(j + 1, -1);
    if (slot[j] < 0) slot[j] = int(columns.size()), columns.push_back(j);
    return slot[j];
  };
  for (size_t i = 0; i < nv; ++i)
    if (dist[i] < band && mesh.part[i] == 0 && !mesh.seam[i]) free.push_back(uint32_t(i));
  std::vector<int> row(nv, -1);  // vertex -> row of `w` (the free ones and their neighbours)
  std::vector<uint32_t> rows;
  for (uint32_t i : free)
    for (uint32_t v : nbr[i])
      for (uint32_t x : {i, v})
        if (row[x] < 0) row[x] = int(rows.size()), rows.push_back(x);
  for (uint32_t x : rows)
    for (int k = 0; k < 4; ++k)
      if (mesh.weights[x][k] > 0) column(mesh.joints[x][k]);
  const size_t nc = columns.size();
  std::vector<float> w(rows.size() * nc, 0.0f);
  for (size_t r = 0; r < rows.size(); ++r)
    for (int k = 0; k < 4; ++k)
      if (mesh.weights[rows[r]][k] > 0) w[r * nc + slot[mesh.joints[rows[r]][k]]] += mesh.weights[rows[r]][k];
  std::vector<float> mean(nc);
  std::vector<std::vector<float>> ew(nv);  // each free vertex's edges' weights, 1 / length
  for (uint32_t i : free) {
    ew[i].resize(nbr[i].size());
    for (size_t k = 0; k < nbr[i].size(); ++k)
      ew[i][k] = 1.0f / std::max(kShortestEdge, glm::distance(mesh.positions[i], mesh.positions[nbr[i][k]]));
  }
  for (int iteration = 0; iteration < 4000; ++iteration) {
    float change = 0;
    for (uint32_t i : free) {
      std::fill(mean.begin(), mean.end(), 0.0f);
      float total = 0;
      for (size_t k = 0; k < nbr[i].size(); ++k) {
        const uint32_t v = nbr[i][k];
        total += ew[i][k];
        for (size_t c = 0; c < nc; ++c) mean[c] += ew[i][k] * w[row[v] * nc + c];
      }
      float* own = &w[row[i] * nc];
      for (size_t c = 0; c < nc; ++c) {
        const float step = mean[c] / total - own[c];
        change = std::max(change, std::abs(step));
        own[c] += kOverRelaxation * step;
      }
    }
    if (change < 1e-5f) break;
  }
  for (uint32_t i : free) {
    std::vector<std::pair<float, int>> ws;
    for (size_t c = 0; c < nc; ++c)
      if (w[row[i] * nc + c] > 0) ws.push_back({w[row[i] * nc + c], columns[c]});
    std::sort(ws.rbegin(), ws.rend());
    store_influences(ws, 0.01f, &mesh.joints[i], &mesh.weights[i]);  // as skin_vertex does
  }
}

struct BodyModel {
  std::unique_ptr<modeler::ImplicitSurface> surface;
  std::unique_ptr<SubField> whole;
  std::vector<PieceSpec> pieces;  // torso, arm L, arm R, leg L, leg R
  std::vector<Bone> bones;
  std::vector<std::vector<int>> region_bones;  // per Region
  float height = 1.75f;
};

Result<BodyModel> analyse(const modeler::Body& body, const MesherOptions& options) {
  BodyModel m;
  if (!body.skeleton) return Error{"", body.name, "the body has no skeleton"};
  if (body.primitives.empty()) return Error{"", body.name, "the body has no primitives"};
  const modeler::Skeleton& sk = *body.skeleton;
  const auto& joints = sk.joints();
  std::unordered_map<std::string, int> id;
  const char* required[] = {"sacroiliac", "vl5", "vt10", "vc7", "skullbase", "skull_tip",
                            "l_sternoclavicular", "l_shoulder", "l_elbow", "l_wrist", "l_middle1", "l_middle_tip",
                            "r_sternoclavicular", "r_shoulder", "r_elbow", "r_wrist", "r_middle1", "r_middle_tip",
                            "l_hip", "l_knee", "l_ankle", "l_metatarsophalangeal", "l_toe_tip",
                            "r_hip", "r_knee", "r_ankle", "r_metatarsophalangeal", "r_toe_tip"};
  for (const char* n : required) {
    int j = sk.find_joint(n);
    if (j < 0) return Error{"", "skeleton " + sk.name, std::string("the mesher needs joint \"") + n + "\""};
    id[n] = j;
  }
  modeler::Posture posture = sk.posture(body.sample_posture);
  m.surface = std::make_unique<modeler::ImplicitSurface>(body, posture);
  m.whole = std::make_unique<SubField>(*m.surface);
  const auto& world = m.surface->joint_transforms();
  auto pos = [&](const char* n) { return glm::vec3(world[id.at(n)][3]); };
  m.height = body.height();
  const float scale = m.height / 1.75f;
  auto descends = [&](int j, int ancestor) {
    for (; j >= 0; j = joints[j].parent)
      if (j == ancestor) return true;
    return false;
  };
  // Primitive ownership: limb roots take their descendants, the torso the rest.
  const int limb_root[4] = {id["l_shoulder"], id["r_shoulder"], id["l_hip"], id["r_hip"]};
  std::vector<int> owner(body.primitives.size(), 0);
  for (size_t i = 0; i < body.primitives.size(); ++i)
    for (int l = 0; l < 4; ++l)
      if (descends(body.primitives[i].joint, limb_root[l])) owner[i] = 1 + l;

  // Bones: a segment per joint with children (to its chain child, or the mean of its children).
  auto add_bone = [&](int joint, glm::vec3 a, glm::vec3 b) {
    m.bones.push_back({joint, a, b});
    return int(m.bones.size() - 1);
  };
  auto bone_of = [&](int j) {
    std::vector<int> kids;
    for (size_t c = 0; c < joints.size(); ++c)
      if (joints[c].parent == j) kids.push_back(int(c));
    glm::vec3 a(world[j][3]), b(0);
    for (int c : kids) b += glm::vec3(world[c][3]);
    b = kids.empty() ? a : b / float(kids.size());
    return add_bone(j, a, b);
  };
  m.region_bones.assign(kRegions, {});
  int b_sacro = add_bone(id["sacroiliac"], pos("sacroiliac"), pos("vl5"));
  int b_vl5 = add_bone(id["vl5"], pos("vl5"), pos("vt10"));
  int b_vt10 = add_bone(id["vt10"], pos("vt10"), pos("vc7"));
  int b_vc7 = add_bone(id["vc7"], pos("vc7"), pos("skullbase"));
  int b_skull = add_bone(id["skullbase"], pos("skullbase"), pos("skull_tip"));
  m.region_bones[kTorso] = {b_sacro, b_vl5, b_vt10, b_vc7, b_skull};
  m.region_bones[kHead] = {b_vc7, b_skull};
  for (int side = 0; side < 2; ++side) {
    std::string s = side == 0 ? "l_" : "r_";
    auto J = [&](const char* n) { return id.at(s + n); };
    auto P = [&](const char* n) { return pos((s + n).c_str()); };
    int b_sc = add_bone(J("sternoclavicular"), P("sternoclavicular"), P("shoulder"));
    int b_sh = add_bone(J("shoulder"), P("shoulder"), P("elbow"));
    int b_el = add_bone(J("elbow"), P("elbow"), P("wrist"));
    int b_wr = add_bone(J("wrist"), P("wrist"), P("middle1"));
    int b_hip = add_bone(J("hip"), P("hip"), P("knee"));
    int b_kn = add_bone(J("knee"), P("knee"), P("ankle"));
    int b_an = add_bone(J("ankle"), P("ankle"), P("metatarsophalangeal"));
    int b_mt = add_bone(J("metatarsophalangeal"), P("metatarsophalangeal"), P("toe_tip"));
    m.region_bones[kTorso].insert(m.region_bones[kTorso].end(), {b_sc, b_hip});
    m.region_bones[side == 0 ? kArmL : kArmR] = {b_sc, b_sh, b_el, b_wr};
    auto& hand = m.region_bones[side == 0 ? kHandL : kHandR];
    hand = {b_el, b_wr};
    for (size_t j = 0; j < joints.size(); ++j)
      if (int(j) != J("wrist") && descends(int(j), J("wrist"))) {
        bool has_child = false;
        for (const auto& c : joints) has_child |= c.parent == int(j);
        if (has_child) hand.push_back(bone_of(int(j)));
      }
    m.region_bones[side == 0 ? kLegL : kLegR] = {b_sacro, b_hip, b_kn, b_an};
    m.region_bones[side == 0 ? kFootL : kFootR] = {b_kn, b_an, b_mt};
  }

  // Pieces.
  auto prims_of = [&](int o) {
    std::vector<int> v;
    for (size_t i = 0; i < owner.size(); ++i)
      if (owner[i] == o) v.push_back(int(i));
    return v;
  };
  auto lerp = [](glm::vec3 a, glm::vec3 b, float t) { return a + t * (b - a); };
  {
    PieceSpec t;
    t.axis = {pos("sacroiliac"), pos("vl5"), pos("vt10"), pos("vc7"), lerp(pos("vc7"), pos("skullbase"), 0.5f)};
    t.links = 3;
    t.region = kTorso;
    t.ext_region = kHead;
    t.ext_part = MeshPart::kHead;
    t.prims = prims_of(0);
    t.cup_center = lerp(pos("skullbase"), pos("skull_tip"), 0.45f);
    t.cup_pole = pos("skull_tip") - pos("skullbase");
    t.ext_voxel = options.vdb_voxel_m * scale;
    m.pieces.push_back(std::move(t));
  }
  for (int side = 0; side < 2; ++side) {
    std::string s = side == 0 ? "l_" : "r_";
    auto P = [&](const char* n) { return pos((s + n).c_str()); };
    PieceSpec a;
    // The arm starts at the sternoclavicular joint and sees the clavicle and trapezius too: it
    // overlaps the torso at every density (the union always joins them) and carries the blend
    // of the deltoid into the shoulder.
    a.axis = {P("sternoclavicular"), P("shoulder"), P("elbow"), lerp(P("elbow"), P("wrist"), 0.92f)};
    a.links = 2;
    a.region = side == 0 ? kArmL : kArmR;
    a.ext_region = side == 0 ? kHandL : kHandR;
    a.ext_part = side == 0 ? MeshPart::kLeftHand : MeshPart::kRightHand;
    a.prims = prims_of(1 + side);
    for (size_t i = 0; i < body.primitives.size(); ++i)
      if (body.primitives[i].joint == id.at(s + "sternoclavicular")) a.prims.push_back(int(i));
    a.cup_center = lerp(P("wrist"), P("middle1"), 0.55f);
    a.cup_pole = P("middle_tip") - P("wrist");
    a.ext_voxel = options.vdb_hand_voxel_m * scale;
    m.pieces.push_back(std::move(a));
  }
  for (int side = 0; side < 2; ++side) {
    std::string s = side == 0 ? "l_" : "r_";
    auto P = [&](const char* n) { return pos((s + n).c_str()); };
    PieceSpec l;
    glm::vec3 in = P("hip") - 0.06f * scale * glm::normalize(P("knee") - P("hip"));
    l.axis = {in, P("hip"), P("knee"), lerp(P("knee"), P("ankle"), 0.86f)};
    l.links = 2;
    l.region = side == 0 ? kLegL : kLegR;
    l.ext_region = side == 0 ? kFootL : kFootR;
    l.ext_part = side == 0 ? MeshPart::kLeftFoot : MeshPart::kRightFoot;
    l.prims = prims_of(3 + side);
    // From just in front of the ankle the lower shank, heel, sole and toes are all in sight.
    glm::vec3 c = lerp(P("ankle"), P("metatarsophalangeal"), 0.15f);
    l.cup_center = c;
    l.cup_pole = P("ankle") - P("knee");  // latitudes sweep from the rim down, not over the top
    l.ext_voxel = options.vdb_voxel_m * scale;
    m.pieces.push_back(std::move(l));
  }
  for (PieceSpec& p : m.pieces) {
    if (p.prims.empty()) return Error{"", body.name, "a body piece has no primitives"};
    p.field = std::make_unique<SubField>(*m.surface, p.prims);
    std::vector<Frame> f = ring_frames(p.axis, 2);
    p.seam_frame = f.back();
  }
  return m;
}

// The OpenVDB extremity of a piece: box around the primitives beyond the seam plane and the
// seam ring's neighbourhood.
Status build_vdb_extremity(const modeler::ImplicitSurface& surface, PieceSpec& p, float voxel_scale) {
  const Frame& sf = p.seam_frame;
  modeler::Aabb box;
  // Surface beyond the plane lies within the supports of the piece's primitives that reach
  // past the plane; cut the box to the far side of the plane (plus a margin).
  std::vector<float> radii;
  PieceMesh scratch;
  Frame f = sf;
  cast_ring(*p.field, f, 32, scratch, 0, 0, 0, &radii);
  float r = *std::max_element(radii.begin(), radii.end());
  // Far extent: sample rays from the cup centre.
  box.extend(sf.c - glm::vec3(1.4f * r));
  box.extend(sf.c + glm::vec3(1.4f * r));
  const int n = 24;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      float th = glm::two_pi<float>() * i / n, ph = glm::pi<float>() * (j + 0.5f) / n;
      glm::vec3 d(std::sin(ph) * std::cos(th), std::cos(ph), std::sin(ph) * std::sin(th));
      if (auto t = p.field->outermost(p.cup_center, d, 1.0f)) {
        glm::vec3 q = p.cup_center + (*t) * d;
        if (glm::dot(q - sf.c, sf.t) > 0) box.extend(q);
      }
    }
  // Rays miss thin features: pad by 2 cm.
  box.min -= glm::vec3(0.02f);
  box.max += glm::vec3(0.02f);
  // Only the primitives whose support meets the box matter there.
  std::vector<int> near;
  for (int i : p.prims) {
    const modeler::Aabb& sb = surface.primitives()[i].support;
    if (sb.min.x <= box.max.x && sb.max.x >= box.min.x && sb.min.y <= box.max.y && sb.max.y >= box.min.y &&
        sb.min.z <= box.max.z && sb.max.z >= box.min.z)
      near.push_back(i);
  }
  SubField local(surface, near);
  auto e = detail::mesh_extremity(local, box, p.ext_voxel * voxel_scale, sf.c, sf.t);
  if (!e) return e.error();
  p.vdb = std::move(*e);
  return Ok{};
}

double distance_to_skin(const SubField& f, const glm::vec3& x) {
  glm::vec3 y = f.project(x, 0.2f, 20);
  glm::vec3 g;
  float v = f.field_gradient(y, &g) - modeler::kIso;
  double d = glm::distance(x, y);
  // Not converged (flat field): fall back to the first-order estimate.
  if (std::abs(v) > 1e-3f) {
    glm::vec3 g0;
    float v0 = f.field_gradient(x, &g0) - modeler::kIso;
    float gl = glm::length(g0);
    if (gl > 1e-6f) d = std::max(d, double(std::abs(v0) / gl));
  }
  return d;
}

// Puts the OpenVDB extremities back in place of their stand-in fans after the union. False when
// the union changed a fan (then nothing is modified).
bool reattach(PlainMesh& m, const std::vector<Attachment>& atts) {
  auto key = [](const glm::vec3& p) {
    uint32_t b[3];
    std::memcpy(b, &p, 12);
    return (uint64_t(b[0]) * 0x9E3779B97F4A7C15ull) ^ (uint64_t(b[1]) * 0xC2B2AE3D27D4EB4Full) ^ b[2];
  };
  std::unordered_multimap<uint64_t, uint32_t> at;
  for (uint32_t i = 0; i < m.positions.size(); ++i) at.emplace(key(m.positions[i]), i);
  auto find = [&](const glm::vec3& p) -> int64_t {
    auto r = at.equal_range(key(p));
    for (auto it = r.first; it != r.second; ++it)
      if (m.positions[it->second] == p) return it->second;
    return -1;
  };
  std::vector<char> drop(m.indices.size() / 3, 0);
  std::vector<std::vector<uint32_t>> ring_ids(atts.size());
  std::vector<int64_t> poles(atts.size());
  for (size_t a = 0; a < atts.size(); ++a) {
    poles[a] = find(atts[a].pole);
    if (poles[a] < 0) return false;
    std::unordered_map<uint32_t, int> in_ring;
    for (const glm::vec3& p : atts[a].ring) {
      int64_t v = find(p);
      if (v < 0) return false;
      in_ring[uint32_t(v)] = 1;
      ring_ids[a].push_back(uint32_t(v));
    }
    size_t fan = 0;
    for (size_t t = 0; t < drop.size(); ++t) {
      const uint32_t* v = &m.indices[3 * t];
      if (v[0] != poles[a] && v[1] != poles[a] && v[2] != poles[a]) continue;
      for (int k = 0; k < 3; ++k)
        if (v[k] != poles[a] && !in_ring.count(v[k])) return false;
      drop[t] = 1;
      ++fan;
    }
    if (fan != atts[a].ring.size()) return false;
  }
  std::vector<uint32_t> idx;
  idx.reserve(m.indices.size());
  for (size_t t = 0; t < drop.size(); ++t)
    if (!drop[t]) idx.insert(idx.end(), m.indices.begin() + 3 * t, m.indices.begin() + 3 * t + 3);
  for (size_t a = 0; a < atts.size(); ++a) {
    const uint32_t R = uint32_t(atts[a].ring.size()), base = uint32_t(m.positions.size());
    m.positions.insert(m.positions.end(), atts[a].ext.positions.begin(), atts[a].ext.positions.end());
    for (uint32_t i : atts[a].tris) idx.push_back(i < R ? ring_ids[a][i] : base + (i - R));
  }
  m.indices = std::move(idx);
  // The poles are no longer used: compact.
  std::vector<int64_t> map(m.positions.size(), -1);
  std::vector<glm::vec3> pos;
  for (uint32_t& i : m.indices) {
    if (map[i] < 0) { map[i] = int64_t(pos.size()); pos.push_back(m.positions[i]); }
    i = uint32_t(map[i]);
  }
  m.positions = std::move(pos);
  return true;
}

// The union can leave a tiny closed bubble where an extended ray enclosed a pocket of the
// blend outside the neighbour; drop components under 1 % of the triangles (never a limb).
void drop_small_components(PlainMesh& m) {
  const size_t nv = m.positions.size(), nt = m.indices.size() / 3;
  std::vector<int> parent(nv);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int x) { while (parent[x] != x) x = parent[x] = parent[parent[x]]; return x; };
  for (size_t t = 0; t < nt; ++t) {
    parent[find(int(m.indices[3 * t + 1]))] = find(int(m.indices[3 * t]));
    parent[find(int(m.indices[3 * t + 2]))] = find(int(m.indices[3 * t]));
  }
  std::unordered_map<int, size_t> size;
  for (size_t t = 0; t < nt; ++t) ++size[find(int(m.indices[3 * t]))];
  if (size.size() < 2) return;
  std::vector<uint32_t> kept;
  for (size_t t = 0; t < nt; ++t)
    if (size[find(int(m.indices[3 * t]))] * 100 >= nt)
      kept.insert(kept.end(), m.indices.begin() + 3 * t, m.indices.begin() + 3 * t + 3);
  // Unreferenced vertices are compacted away.
  std::vector<int64_t> map(nv, -1);
  PlainMesh out;
  for (uint32_t& i : kept) {
    if (map[i] < 0) { map[i] = int64_t(out.positions.size()); out.positions.push_back(m.positions[i]); }
    i = uint32_t(map[i]);
  }
  out.indices = std::move(kept);
  m = std::move(out);
}

}  // namespace

// See internal.h.
size_t detail::fit_creases(PlainMesh& m, const SubField& skin, float tol, float max_move, float min_edge, int passes,
                   const std::vector<char>& frozen) {
  constexpr uint32_t kNone = UINT32_MAX;
  const size_t n0 = m.positions.size();
  std::vector<glm::vec3> chord = m.positions;
  auto is_frozen = [&](uint32_t v) { return v < frozen.size() && frozen[v]; };
  auto off_skin = [&](const glm::vec3& p) {
    glm::vec3 g;
    float f = skin.field_gradient(p, &g) - modeler::kIso;
    float gl = glm::length(g);
    return gl > 1e-6f && std::abs(f) > tol * gl;
  };
  for (size_t i = 0; i < n0; ++i)
    if (!is_frozen(uint32_t(i)) && off_skin(m.positions[i])) m.positions[i] = skin.project(m.positions[i], max_move);
  std::vector<char> active(m.indices.size() / 3, 1);  // triangles whose edges are tested
  for (int pass = 0; pass < passes; ++pass) {
    std::unordered_map<uint64_t, uint32_t> split;
    auto ekey = [](uint32_t a, uint32_t b) {
      if (a > b) std::swap(a, b);
      return (uint64_t(a) << 32) | b;
    };
    const size_t nt = m.indices.size() / 3;
    split.reserve(pass == 0 ? nt * 2 : nt / 4);
    const size_t before = m.positions.size();
    for (size_t t = 0; t < nt; ++t)
      for (int e = 0; active[t] && e < 3; ++e) {
        uint32_t a = m.indices[3 * t + e], b = m.indices[3 * t + (e + 1) % 3];
        if (is_frozen(a) && is_frozen(b)) continue;
        auto [it, fresh] = split.try_emplace(ekey(a, b), kNone);
        if (!fresh) continue;
        const glm::vec3 pa = m.positions[a], pb = m.positions[b];
        float len = glm::distance(pa, pb);
        if (len < min_edge) continue;
        glm::vec3 mid = 0.5f * (pa + pb);
        if (!off_skin(mid)) continue;
        it->second = uint32_t(m.positions.size());
        m.positions.push_back(skin.project(mid, std::min(max_move, 0.5f * len)));
        chord.push_back(0.5f * (chord[a] + chord[b]));
      }
    if (m.positions.size() == before) break;
    std::vector<uint32_t> out;
    std::vector<char> next_active;
    out.reserve(m.indices.size() * 2);
    next_active.reserve(nt * 2);
    for (size_t t = 0; t < nt; ++t) {
      // The triangle as a polygon: corners and the midpoints of split edges, in order.
      uint32_t poly[6];
      bool is_mid[6];
      int n = 0, splits = 0;
      for (int e = 0; e < 3; ++e) {
        uint32_t a = m.indices[3 * t + e], b = m.indices[3 * t + (e + 1) % 3];
        poly[n] = a, is_mid[n++] = false;
        auto it = split.find(ekey(a, b));
        if (it != split.end() && it->second != kNone) poly[n] = it->second, is_mid[n++] = true, ++splits;
      }
      auto tri = [&](int i, int j, int k) {
        out.insert(out.end(), {poly[i % n], poly[j % n], poly[k % n]});
        next_active.push_back(splits > 0);
      };
      if (splits == 0) {
        tri(0, 1, 2);
      } else if (splits == 3) {
        tri(5, 0, 1), tri(1, 2, 3), tri(3, 4, 5), tri(1, 3, 5);
      } else if (splits == 1) {
        int p = 0;
        while (!is_mid[p]) ++p;
        tri(p, p + 1, p + 2), tri(p, p + 2, p + 3);
      } else {
        // The corner between the two midpoints is cut off; the rest is a quad (mB, x, y, mA)
        // split along its shorter diagonal (on the chord surface, where it is planar).
        int c = 0;
        while (!(is_mid[(c + n - 1) % n] && is_mid[(c + 1) % n] && !is_mid[c])) ++c;
        tri(c + n - 1, c, c + 1);
        int q0 = c + 1, q1 = c + 2, q2 = c + 3, q3 = c + 4;
        float d02 = glm::distance(chord[poly[q0 % n]], chord[poly[q2 % n]]);
        float d13 = glm::distance(chord[poly[q1 % n]], chord[poly[q3 % n]]);
        if (d02 <= d13) tri(q0, q1, q2), tri(q0, q2, q3);
        else tri(q1, q2, q3), tri(q1, q3, q0);
      }
    }
    m.indices = std::move(out);
    active = std::move(next_active);
  }
  // Guard: only triangles with a moved vertex can take part in an intersection.
  const size_t nt = m.indices.size() / 3;
  // Rounds that take vertices half-way back, then rounds that take them all the way back; the
  // last resort puts every vertex back on the chord surface.
  const int kPartial = 10, kRounds = 40;
  for (int round = 0; round < kRounds; ++round) {
    std::vector<uint32_t> moved;
    for (size_t t = 0; t < nt; ++t) {
      const uint32_t* v = &m.indices[3 * t];
      if (m.positions[v[0]] != chord[v[0]] || m.positions[v[1]] != chord[v[1]] || m.positions[v[2]] != chord[v[2]])
        moved.push_back(uint32_t(t));
    }
    std::vector<uint32_t> bad = intersecting_triangles(m.positions, m.indices, moved);
    if (std::getenv("BB_MESHER_DEBUG") && !bad.empty()) {
      glm::vec3 p = m.positions[m.indices[3 * bad[0]]];
      std::fprintf(stderr, "fit guard round %d: %zu of %zu moved triangles intersect, e.g. at (%.3f %.3f %.3f)\n", round,
                   bad.size(), moved.size(), p.x, p.y, p.z);
    }
    if (bad.empty()) break;
    if (round == kRounds - 1) {
      m.positions = chord;
      break;
    }
    // First back part of the way, then (vertices of triangles still intersecting) all the way.
    const float keep = round < kPartial ? 0.5f : 0.0f;
    std::vector<char> done(m.positions.size(), 0);
    // Partial rounds take back only the most displaced vertex of each intersecting triangle.
    const bool one = round < kPartial;
    for (uint32_t t : bad) {
      int kmax = 0;
      float dmax = -1;
      for (int k = 0; k < 3; ++k) {
        uint32_t v = m.indices[3 * t + k];
        float dd = glm::distance(m.positions[v], chord[v]);
        if (dd > dmax) dmax = dd, kmax = k;
      }
      for (int k = 0; k < 3; ++k) {
        if (one && k != kmax) continue;
        uint32_t v = m.indices[3 * t + k];
        if (!done[v]) m.positions[v] = chord[v] + keep * (m.positions[v] - chord[v]), done[v] = 1;
      }
    }
  }
  return m.positions.size() - n0;
}

std::vector<glm::vec3> detail::sample_contour(const SubField& field, const glm::vec3& center, const glm::vec3& tangent,
                                              const glm::vec3& reference, int points) {
  Frame f;
  f.c = center;
  f.t = glm::normalize(tangent);
  f.u = glm::normalize(reference - glm::dot(reference, f.t) * f.t);
  f.v = glm::cross(f.t, f.u);
  PieceMesh mesh;
  cast_ring(field, f, points, mesh, 0, 0, 0);
  return mesh.positions;
}

std::vector<LodDensity> default_lod_chain() {
  std::vector<LodDensity> c(4);
  // LOD 0: dense contours and the full-resolution OpenVDB extremities.
  c[0].torso = {12, 40};
  c[0].arm = {12, 20};
  c[0].leg = {12, 24};
  c[0].vdb_extremities = true;
  c[0].crease_tolerance = 0.0015f;  // crease fitting: armpits, groin and shoulders within 0.15 % of the height
  c[0].screen_coverage = 0.5f;
  c[1].torso = {8, 28};
  c[1].arm = {7, 14};
  c[1].leg = {7, 16};
  c[1].hand_rings = 5, c[1].foot_rings = 6, c[1].head_rings = 7;
  c[1].screen_coverage = 0.25f;
  // The coarse levels are crease-fitted too: where the union joins the arms to the torso their
  // pieces' facets crossed outside the skin, a shelf across the front of the shoulders in the bind
  // posture and flaps over them in the walk (`CoarseLevelsFollowTheSkinWhereTheArmsJoinTheTorso`).
  c[1].crease_tolerance = 0.003f;
  c[2].torso = {5, 18};
  c[2].arm = {4, 10};
  c[2].leg = {4, 10};
  c[2].hand_rings = 3, c[2].foot_rings = 4, c[2].head_rings = 5;
  c[2].screen_coverage = 0.1f;
  // LOD 2 only where the skin is farther than 1.2 % of the height: at 0.5 % the fitting also moved
  // the vertices in the armpits' creases, and on seeded variants 1 and 2 they stood out as bright
  // spikes.
  c[2].crease_tolerance = 0.012f;
  c[3].torso = {3, 10};
  c[3].arm = {2, 6};
  c[3].leg = {2, 6};
  c[3].hand_rings = 2, c[3].foot_rings = 2, c[3].head_rings = 3;
  c[3].screen_coverage = 0.02f;
  return c;
}

const StageTimes& last_stage_times() { return g_times; }

Result<std::vector<Lod>> build_lods(const modeler::Body& body, const MesherOptions& options) {
  g_times = {};
  const std::vector<LodDensity> chain = options.lods.empty() ? default_lod_chain() : options.lods;
  for (size_t i = 0; i < chain.size(); ++i) {
    const LodDensity& d = chain[i];
    for (const PartDensity* p : {&d.torso, &d.arm, &d.leg})
      if (p->contours < 1 || p->points < 4)
        return Error{"", "lods[" + std::to_string(i) + "]", "contours must be >= 1 and points >= 4"};
    if (d.hand_rings < 1 || d.foot_rings < 1 || d.head_rings < 1)
      return Error{"", "lods[" + std::to_string(i) + "]", "extremity rings must be >= 1"};
  }
  auto t0 = Clock::now();
  auto model = analyse(body, options);
  if (!model) return model.error();
  BodyModel& m = *model;
  g_whole = m.whole.get();
  g_times.field = since(t0);

  bool any_vdb = std::any_of(chain.begin(), chain.end(), [](const LodDensity& d) { return d.vdb_extremities; });
  std::vector<double> extremity_error(m.pieces.size(), 0);
  if (any_vdb) {
    t0 = Clock::now();
    // Five extremities on two cores.
    std::vector<Status> st(m.pieces.size(), Ok{});
    std::thread worker([&] {
      for (size_t i = 0; i < m.pieces.size(); i += 2) st[i] = build_vdb_extremity(*m.surface, m.pieces[i], 1.0f);
    });
    for (size_t i = 1; i < m.pieces.size(); i += 2) st[i] = build_vdb_extremity(*m.surface, m.pieces[i], 1.0f);
    worker.join();
    // The error names the extremity and where its seam is: a body without the primitives that carry
    // the skin across a seam (a neck, a wrist, an ankle) has no skin there for the plane to cut.
    static constexpr const char* kExtremity[] = {"body", "head", "left hand", "right hand", "left foot", "right foot"};
    static constexpr const char* kSeam[] = {"", "neck", "left wrist", "right wrist", "left ankle", "right ankle"};
    for (size_t i = 0; i < st.size(); ++i)
      if (!st[i]) {
        const auto part = std::min<std::size_t>(static_cast<std::size_t>(m.pieces[i].ext_part), 5);
        return Error{"", body.name + ": " + kExtremity[part],
                     st[i].error().reason + " (its seam at the " + kSeam[part] +
                         ": does the body still have the primitives that carry the skin across it?)"};
      }
    g_times.extremities = since(t0);
  }

  // The reference skin for the error report: OpenVDB at a fine voxel, vertices on the skin.
  PlainMesh reference;
  std::vector<glm::vec3> reference_points;
  if (options.error_samples > 0) {
    t0 = Clock::now();
    reference = detail::reference_mesh(*m.whole, 0.005f * m.height / 1.75f);
    // Skin samples: the reference's vertices that Newton put on the skin (where the reference
    // bridged a gap narrower than its voxel, between fingers, some stay off it).
    for (const glm::vec3& p : reference.positions) {
      glm::vec3 g;
      float f = m.whole->field_gradient(p, &g) - modeler::kIso;
      if (std::abs(f) <= 1e-4f * glm::length(g)) reference_points.push_back(p);
    }
    if (std::getenv("BB_MESHER_DEBUG"))
      std::fprintf(stderr, "reference: %zu vertices, %zu on the skin\n", reference.positions.size(),
                   reference_points.size());
    if (reference_points.size() > size_t(options.error_samples)) {
      std::mt19937 rng(7);
      std::shuffle(reference_points.begin(), reference_points.end(), rng);
      reference_points.resize(options.error_samples);
    }
    g_times.errors += since(t0);
  }

  std::vector<Lod> lods;
  for (size_t level = 0; level < chain.size(); ++level) {
    const LodDensity& d = chain[level];
    auto lod_start = Clock::now();
    t0 = Clock::now();
    std::vector<PieceMesh> pieces;
    std::vector<Attachment> attachments(d.vdb_extremities ? m.pieces.size() : 0);
    std::vector<float> windows(m.pieces.size(), 0.06f);
    for (size_t i = 0; i < m.pieces.size(); ++i) {
      const PieceSpec& spec = m.pieces[i];
      const PartDensity& pd = i == 0 ? d.torso : (i < 3 ? d.arm : d.leg);
      int cup = i == 0 ? d.head_rings : (i < 3 ? d.hand_rings : d.foot_rings);
      int cup_points = i == 0 ? d.head_points : (i < 3 ? d.hand_points : d.foot_points);
      float spacing = axis_length(spec.axis) / float(pd.contours * spec.links);
      float gap = std::max(0.003f * m.height / 1.75f, 0.35f * spacing);
      // Rings are cast in planes across the axis, their tangents smoothed over `windows[i]` either
      // side: where the axis bends (the spine's lumbar curve) neighbouring planes meet at about
      // window / bend angle from the axis, and a belly reaching farther out than that folds the
      // piece (rings crossing). A piece that intersects itself is cast again with the tangent
      // smoothed over a wider stretch; the fewest intersections win.
      PieceMesh best;
      size_t best_crossings = SIZE_MAX;
      for (float w : {0.06f, 0.12f, 0.2f, 0.3f}) {
        Attachment att;
        PieceMesh p = build_piece(spec, pd, cup, cup_points, d.vdb_extremities, gap, d.crease_tolerance > 0,
                                  d.vdb_extremities ? &att : nullptr, w);
        const size_t crossings = check_mesh(p.positions, p.indices, true).self_intersections;
        if (crossings < best_crossings) {
          best = std::move(p);
          best_crossings = crossings;
          windows[i] = w;
          if (d.vdb_extremities) attachments[i] = std::move(att);
        }
        if (crossings == 0) break;
      }
      if (std::getenv("BB_MESHER_DEBUG") && windows[i] != 0.06f)
        std::fprintf(stderr, "lod %zu piece %zu: tangent window %.2f m, %zu crossings\n", level, i, windows[i],
                     best_crossings);
      pieces.push_back(std::move(best));
    }
    g_times.contours += since(t0);

    t0 = Clock::now();
    std::vector<PlainMesh> plain;
    for (const PieceMesh& p : pieces) plain.push_back({p.positions, p.indices});
    if (std::getenv("BB_MESHER_DEBUG"))
      for (size_t i = 0; i < pieces.size(); ++i) {
        MeshCheck c = check_mesh(pieces[i].positions, pieces[i].indices, true);
        std::fprintf(stderr, "lod %zu piece %zu: closed %d manifold %d oriented %d self-x %zu\n", level, i, c.closed,
                     c.manifold, c.oriented, c.self_intersections);
        for (size_t k = 0; k < std::min<size_t>(c.intersecting.size(), 8); ++k) {
          for (size_t tt : {c.intersecting[k].first, c.intersecting[k].second}) {
            std::fprintf(stderr, "   tri %zu:", tt);
            for (int q = 0; q < 3; ++q) {
              uint32_t vi = pieces[i].indices[3 * tt + q];
              glm::vec3 a = pieces[i].positions[vi];
              std::fprintf(stderr, " v%u(%.3f %.3f %.3f)", vi, a.x, a.y, a.z);
            }
            std::fprintf(stderr, "\n");
          }
        }
      }
    auto joined = detail::mesh_union(plain);
    if (!joined) return Error{"", body.name + ": lods[" + std::to_string(level) + "]", joined.error().message()};
    if (!attachments.empty() && !reattach(*joined, attachments)) {
      // The union touched a stand-in fan: unite the pieces with their extremities (slower).
      if (std::getenv("BB_MESHER_DEBUG")) std::fprintf(stderr, "lod %zu: reattach failed, full union\n", level);
      std::vector<PlainMesh> full;
      for (size_t i = 0; i < m.pieces.size(); ++i) {
        const PieceSpec& spec = m.pieces[i];
        const PartDensity& pd = i == 0 ? d.torso : (i < 3 ? d.arm : d.leg);
        int cup = i == 0 ? d.head_rings : (i < 3 ? d.hand_rings : d.foot_rings);
        float spacing = axis_length(spec.axis) / float(pd.contours * spec.links);
        float gap = std::max(0.003f * m.height / 1.75f, 0.35f * spacing);
        PieceMesh p = build_piece(spec, pd, cup, 0, true, gap, d.crease_tolerance > 0, nullptr, windows[i]);
        full.push_back({p.positions, p.indices});
        pieces[i] = std::move(p);
      }
      attachments.clear();
      joined = detail::mesh_union(full);
      if (!joined) return Error{"", body.name + ": lods[" + std::to_string(level) + "]", joined.error().message()};
    }
    for (const Attachment& a : attachments) pieces.push_back(a.ext);  // for the attribute lookup
    drop_small_components(*joined);
    if (std::getenv("BB_MESHER_DEBUG")) {
      MeshCheck c = check_mesh(joined->positions, joined->indices, true);
      std::fprintf(stderr, "lod %zu union: closed %d manifold %d self-x %zu\n", level, c.closed, c.manifold,
                   c.self_intersections);
      for (size_t k = 0; k < std::min<size_t>(c.intersecting.size(), 3); ++k) {
        glm::vec3 a = joined->positions[joined->indices[3 * c.intersecting[k].first]];
        std::fprintf(stderr, "   at (%.3f %.3f %.3f)\n", a.x, a.y, a.z);
      }
    }
    g_times.joining += since(t0);
    // The union's vertices where they were before the crease fitting moved some onto the skin: a
    // moved vertex is still its piece's and takes its attributes from there (only the vertices the
    // fitting adds blend their neighbours'). Empty on a level without fitting.
    std::vector<glm::vec3> unfitted;
    if (d.crease_tolerance > 0) {
      t0 = Clock::now();
      unfitted = joined->positions;
      // Extremity and seam vertices (by exact position) stay as they are.
      std::unordered_map<uint64_t, const glm::vec3*> tagged;
      for (const PieceMesh& p : pieces)
        for (size_t i = 0; i < p.positions.size(); ++i)
          if (p.part[i] != 0 || p.seam[i]) tagged.emplace(position_key(p.positions[i]), &p.positions[i]);
      std::vector<char> frozen(joined->positions.size(), 0);
      for (size_t i = 0; i < frozen.size(); ++i) {
        auto it = tagged.find(position_key(joined->positions[i]));
        frozen[i] = it != tagged.end() && *it->second == joined->positions[i];
      }
      size_t added = detail::fit_creases(*joined, *m.whole, d.crease_tolerance * m.height, 0.012f * m.height,
                                 0.002f * m.height, d.crease_passes, frozen);
      if (std::getenv("BB_MESHER_DEBUG")) std::fprintf(stderr, "lod %zu: refined, %zu vertices added\n", level, added);
      g_times.refining += since(t0);
    }

    // Attributes: original vertices by exact position, new (intersection) vertices from their
    // neighbours.
    t0 = Clock::now();
    Lod lod;
    SkinnedMesh& mesh = lod.mesh;
    mesh.positions = std::move(joined->positions);
    mesh.indices = std::move(joined->indices);
    const size_t nv = mesh.positions.size();
    struct Attr { uint8_t part, seam; int8_t region; };
    auto key = [](const glm::vec3& p) {
      uint32_t b[3];
      std::memcpy(b, &p, 12);
      return (uint64_t(b[0]) * 0x9E3779B97F4A7C15ull) ^ (uint64_t(b[1]) * 0xC2B2AE3D27D4EB4Full) ^ b[2];
    };
    std::unordered_multimap<uint64_t, std::pair<glm::vec3, Attr>> lookup;
    for (const PieceMesh& p : pieces)
      for (size_t i = 0; i < p.positions.size(); ++i)
        lookup.emplace(key(p.positions[i]), std::make_pair(p.positions[i], Attr{p.part[i], p.seam[i], p.region[i]}));
    mesh.part.assign(nv, 0);
    mesh.seam.assign(nv, 0);
    mesh.joints.assign(nv, glm::u16vec4(0));
    mesh.weights.assign(nv, glm::vec4(0));
    std::vector<char> known(nv, 0);
    std::vector<int8_t> region(nv, -1);  // -1: a vertex the union or the crease fitting made
    for (size_t i = 0; i < nv; ++i) {
      const glm::vec3& was = i < unfitted.size() ? unfitted[i] : mesh.positions[i];
      auto range = lookup.equal_range(key(was));
      for (auto it = range.first; it != range.second; ++it)
        if (it->second.first == was) {
          const Attr& a = it->second.second;
          mesh.part[i] = a.part;
          mesh.seam[i] = a.seam;
          region[i] = a.region;
          skin_vertex(mesh.positions[i], m.bones, m.region_bones[a.region], &mesh.joints[i], &mesh.weights[i]);
          known[i] = 1;
          break;
        }
    }
    // New vertices: where the union crossed two pieces, blend the neighbours' weights (a few passes
    // reach vertices next to new ones); a vertex the crease fitting put between vertices of one
    // region is skinned like them. Blended there, a split on the front of a belly edited to 0.3 m
    // mixed its neighbours' hips and spine and turned over in a stride (up to 48 cm2 at LOD 1).
    std::vector<std::vector<uint32_t>> nbr(nv);
    for (size_t t = 0; t < mesh.indices.size(); t += 3)
      for (int e = 0; e < 3; ++e) nbr[mesh.indices[t + e]].push_back(mesh.indices[t + (e + 1) % 3]);
    for (int pass = 0; pass < 8; ++pass) {
      bool all = true;
      for (size_t i = 0; i < nv; ++i) {
        if (known[i]) continue;
        std::unordered_map<int, float> acc;
        int count = 0, one_region = -2;
        for (uint32_t j : nbr[i])
          if (known[j] == 1) {
            ++count;
            one_region = one_region == -2 || one_region == region[j] ? region[j] : -1;
            for (int k = 0; k < 4; ++k)
              if (mesh.weights[j][k] > 0) acc[mesh.joints[j][k]] += mesh.weights[j][k];
          }
        if (count == 0) { all = false; continue; }
        if (one_region >= 0) {
          region[i] = int8_t(one_region);
          skin_vertex(mesh.positions[i], m.bones, m.region_bones[one_region], &mesh.joints[i], &mesh.weights[i]);
          known[i] = 2;
          continue;
        }
        std::vector<std::pair<float, int>> w;
        for (auto& [j, x] : acc) w.push_back({x, j});
        std::sort(w.rbegin(), w.rend());
        store_influences(w, 0.0f, &mesh.joints[i], &mesh.weights[i]);
        known[i] = 2;
      }
      for (auto& k : known)
        if (k == 2) k = 1;
      if (all) break;
    }
    smooth_seam_weights(mesh, region, kSeamBlend * m.height / 1.75f);
    // Normals from the field's gradient; face normals where the gradient vanishes.
    mesh.normals.assign(nv, glm::vec3(0));
    std::vector<glm::vec3> face_n(nv, glm::vec3(0));
    for (size_t t = 0; t < mesh.indices.size(); t += 3) {
      const glm::vec3 &a = mesh.positions[mesh.indices[t]], &b = mesh.positions[mesh.indices[t + 1]],
                      &c = mesh.positions[mesh.indices[t + 2]];
      glm::vec3 n = glm::cross(b - a, c - a);
      for (int k = 0; k < 3; ++k) face_n[mesh.indices[t + k]] += n;
    }
    for (size_t i = 0; i < nv; ++i) {
      glm::vec3 g;
      m.whole->field_gradient(mesh.positions[i], &g);
      glm::vec3 n = -g;
      float len = glm::length(n);
      glm::vec3 fn = face_n[i];
      if (len < 1e-4f || glm::dot(n, fn) < 0) n = fn, len = glm::length(fn);
      mesh.normals[i] = len > 0 ? n / len : glm::vec3(0, 1, 0);
    }
    g_times.skinning += since(t0);
    double build_seconds = since(lod_start);

    LodReport& r = lod.report;
    r.level = int(level);
    r.triangles = mesh.triangle_count();
    r.vertices = nv;
    r.vdb_extremities = d.vdb_extremities;
    r.extremity_triangles = mesh.extremity_triangle_count();
    if (options.check_topology) {
      t0 = Clock::now();
      MeshCheck c = check_mesh(mesh.positions, mesh.indices, true);
      r.closed = c.closed && c.connected_components == 1;
      r.manifold = c.manifold;
      r.oriented = c.oriented;
      r.self_intersections = c.self_intersections > 0;
      r.self_intersection_count = c.self_intersections;
      g_times.checks += since(t0);
    }
    if (!reference_points.empty()) {
      t0 = Clock::now();
      // Mesh -> skin: vertices and area samples, exact distance to the reference skin mesh;
      // skin -> mesh: reference points' exact distance to this mesh.
      std::vector<glm::vec3> pts(mesh.positions);
      std::vector<char> pts_ext(mesh.positions.size());
      for (size_t i = 0; i < mesh.positions.size(); ++i) pts_ext[i] = mesh.part[i] != 0 && !mesh.seam[i];
      std::mt19937 rng(11);
      std::uniform_real_distribution<float> u(0, 1);
      size_t nt = mesh.triangle_count();
      for (int s = 0; s < options.error_samples; ++s) {
        size_t t = std::min(nt - 1, size_t(u(rng) * nt));
        pts_ext.push_back(mesh.extremity_part(3 * t) != 0);
        float r1 = std::sqrt(u(rng)), r2 = u(rng);
        const glm::vec3 &a = mesh.positions[mesh.indices[3 * t]], &b = mesh.positions[mesh.indices[3 * t + 1]],
                        &c = mesh.positions[mesh.indices[3 * t + 2]];
        pts.push_back((1 - r1) * a + r1 * (1 - r2) * b + r1 * r2 * c);
      }
      std::vector<double> d1(pts.size()), d2(reference_points.size());
      distances_to_mesh(reference.positions, reference.indices, pts, d1);
      // Where the reference bridges a gap narrower than its voxel (between fingers), the
      // distance to it overstates the error: a skin point reached from the sample by Newton
      // along the gradient bounds the distance from above.
      for (size_t i = 0; i < pts.size(); ++i) {
        if (d1[i] < 1e-3 * m.height) continue;
        glm::vec3 y = m.whole->project(pts[i], float(d1[i]), 20), g;
        float f = m.whole->field_gradient(y, &g) - modeler::kIso;
        if (std::abs(f) <= 1e-5f * glm::length(g)) d1[i] = std::min(d1[i], double(glm::distance(pts[i], y)));
      }
      distances_to_mesh(mesh.positions, mesh.indices, reference_points, d2);
      double h1 = *std::max_element(d1.begin(), d1.end()), h2 = *std::max_element(d2.begin(), d2.end());
      r.hausdorff_m = std::max(h1, h2);
      r.errors_measured = true;
      r.mean_m = 0.5 * (std::accumulate(d1.begin(), d1.end(), 0.0) / double(d1.size()) +
                        std::accumulate(d2.begin(), d2.end(), 0.0) / double(d2.size()));
      r.hausdorff_rel = r.hausdorff_m / m.height;
      r.mean_rel = r.mean_m / m.height;
      // Extremities: mesh samples on extremity triangles, reference points beyond a seam plane
      // and near that extremity's centre.
      double he = 0;
      glm::vec3 he_at(0);
      const char* he_dir = "";
      for (size_t i = 0; i < pts.size(); ++i)
        if (pts_ext[i] && d1[i] > he) he = d1[i], he_at = pts[i], he_dir = "mesh->skin";
      for (size_t i = 0; i < reference_points.size(); ++i)
        for (const PieceSpec& ps : m.pieces) {
          const glm::vec3& q = reference_points[i];
          if (glm::dot(q - ps.seam_frame.c, ps.seam_frame.t) > 0.01f * m.height / 1.75f &&
              glm::distance(q, ps.cup_center) < 0.25f * m.height / 1.75f) {
            if (d2[i] > he) he = d2[i], he_at = q, he_dir = "skin->mesh";
            break;
          }
        }
      if (std::getenv("BB_MESHER_DEBUG"))
        std::fprintf(stderr, "lod %zu: extremity max %.4f (%s) at (%.3f %.3f %.3f), skin distance there %.4f\n", level, he,
                     he_dir, he_at.x, he_at.y, he_at.z, distance_to_skin(*m.whole, he_at));
      r.extremity_hausdorff_m = he;
      if (std::getenv("BB_MESHER_DEBUG")) {
        size_t i1 = std::max_element(d1.begin(), d1.end()) - d1.begin();
        size_t i2 = std::max_element(d2.begin(), d2.end()) - d2.begin();
        std::fprintf(stderr, "lod %zu: mesh->skin max %.4f at (%.3f %.3f %.3f); skin->mesh max %.4f at (%.3f %.3f %.3f)\n",
                     level, h1, pts[i1].x, pts[i1].y, pts[i1].z, h2, reference_points[i2].x, reference_points[i2].y,
                     reference_points[i2].z);
        // The worst places, at least 5 cm apart, both directions.
        for (int dir = 0; dir < 2; ++dir) {
          const std::vector<double>& dd = dir == 0 ? d1 : d2;
          const std::vector<glm::vec3>& pp = dir == 0 ? pts : reference_points;
          std::vector<size_t> order(dd.size());
          std::iota(order.begin(), order.end(), size_t(0));
          std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return dd[a] > dd[b]; });
          std::vector<glm::vec3> shown;
          for (size_t o : order) {
            if (shown.size() == 6) break;
            bool near = false;
            for (const glm::vec3& q : shown) near |= glm::distance(q, pp[o]) < 0.05f;
            if (near) continue;
            shown.push_back(pp[o]);
            std::fprintf(stderr, "   %s %.4f at (%.3f %.3f %.3f)\n", dir == 0 ? "mesh->skin" : "skin->mesh", dd[o],
                         pp[o].x, pp[o].y, pp[o].z);
          }
        }
      }
      g_times.errors += since(t0);
    }
    if (std::getenv("BB_MESHER_DEBUG") && options.check_topology) {
      MeshCheck c = check_mesh(mesh.positions, mesh.indices, true);
      if (c.connected_components > 1) {
        std::vector<int> comp(nv, -1);
        std::vector<std::vector<uint32_t>> adj(nv);
        for (size_t t = 0; t < mesh.indices.size(); t += 3)
          for (int e = 0; e < 3; ++e) adj[mesh.indices[t + e]].push_back(mesh.indices[t + (e + 1) % 3]);
        int nc = 0;
        for (size_t i = 0; i < nv; ++i) {
          if (comp[i] >= 0) continue;
          std::vector<uint32_t> st{uint32_t(i)};
          comp[i] = nc;
          size_t cnt = 0;
          glm::vec3 sum(0);
          while (!st.empty()) {
            uint32_t v = st.back(); st.pop_back(); ++cnt; sum += mesh.positions[v];
            for (uint32_t w : adj[v]) if (comp[w] < 0) { comp[w] = nc; st.push_back(w); }
          }
          std::fprintf(stderr, "  component %d: %zu vertices around (%.3f %.3f %.3f)\n", nc, cnt, sum.x / cnt, sum.y / cnt, sum.z / cnt);
          ++nc;
        }
      }
      std::fprintf(stderr, "lod %zu: components %zu border %zu nm-edges %zu nm-verts %zu degenerate %zu\n", level,
                   c.connected_components, c.border_edges, c.non_manifold_edges, c.non_manifold_vertices,
                   c.degenerate_triangles);
      for (size_t k = 0; k < std::min<size_t>(c.intersecting.size(), 12); ++k) {
        glm::vec3 a = mesh.positions[mesh.indices[3 * c.intersecting[k].first]];
        std::fprintf(stderr, "lod %zu: self-intersection near (%.3f %.3f %.3f) parts %d\n", level, a.x, a.y, a.z,
                     int(mesh.part[mesh.indices[3 * c.intersecting[k].first]]));
      }
    }
    r.seconds = build_seconds;
    lod.screen_coverage = d.screen_coverage;
    lods.push_back(std::move(lod));
  }
  return lods;
}

}  // namespace bb::mesher
