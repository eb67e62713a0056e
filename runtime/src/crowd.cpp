#include "bb/runtime/crowd.h"

#include <algorithm>
#include <atomic>
#include <bit>
#include <cassert>
#include <cmath>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "bb/runtime/animation.h"
#include "worker_pool.h"

namespace bb::runtime {

namespace {

// ImpostorConfig::fit_quads_to_coverage: the shortest life (impostor frames) of the snapshot a new
// one replaces for the new one to be fitted (FramePlanner::fit_quad).
constexpr std::uint32_t kFitAfterFrames = 2;

// Tight quads: a box's 8 corners projected on the snapshot plane, in window units. Whole texels
// and one texel of margin, inside the window: the quad (`quad`). The snapshot clears three texels
// more (`snapshot`), which the impostor shader's taps at the quad's border reach (else they would
// read what an earlier snapshot left).
struct WindowRects {
  glm::vec4 quad, snapshot;
};

// The projected extent of boxes on the snapshot plane (window units, before the texel snapping):
// snapping the union of extents gives the union of the snapped rects, so a character's parts are
// snapped once.
struct PlaneExtent {
  glm::vec2 lo{1e30f}, hi{-1e30f};
};

// A snapshot camera's projection: a point (x, y, z) of its frame (Ho, Uo, Vo; metres from the
// snapshot's centre) to window units, on the plane through the centre, as the snapshot shader
// projects it.
struct WindowProjection {
  explicit WindowProjection(const SnapshotCamera& cam)
      : inv_half(1.0f / cam.half_size), dist(cam.distance), inv_dist(1.0f / cam.distance), near(1e-3f * cam.distance),
        offset(cam.offset), perspective(cam.perspective) {}
  glm::vec2 operator()(float x, float y, float z) const {
    if (perspective) {
      from_eye(x, y, z);
      return glm::vec2(x, y);
    }
    return glm::vec2(x, y) * inv_half;
  }
  void from_eye(float& x, float& y, float z) const {  // perspective, in place
    const float s = inv_half * dist / std::max(dist + z, near);
    x = (x - offset.x * (z * inv_dist)) * s;  // off-axis window (aligned snapshots)
    y = (y - offset.y * (z * inv_dist)) * s;
  }
  float inv_half, dist, inv_dist, near;
  glm::vec2 offset;
  bool perspective;
};

// Adds the box centre ± a0 ± a1 ± a2 (half edges), centre and edges in the snapshot camera's frame
// (Ho, Uo, Vo; metres from the snapshot's centre), to `e`.
// The corners are summed there: the refresh of a character with part-tight quads projects one box
// per body part (the worst case of the test bed: 1,000 refreshes a frame).
void add_framed_box(const SnapshotCamera& cam, const glm::vec3& c, const glm::vec3& a0, const glm::vec3& a1,
                    const glm::vec3& a2, PlaneExtent& e) {
  // Corner k's signs along the three axes (bits 0, 1, 2 of k); lanes the compiler can vectorize.
  static constexpr float s0[8] = {-1, 1, -1, 1, -1, 1, -1, 1}, s1[8] = {-1, -1, 1, 1, -1, -1, 1, 1},
                         s2[8] = {-1, -1, -1, -1, 1, 1, 1, 1};
  float x[8], y[8], z[8];
  for (int k = 0; k < 8; ++k) {
    x[k] = c.x + s0[k] * a0.x + s1[k] * a1.x + s2[k] * a2.x;
    y[k] = c.y + s0[k] * a0.y + s1[k] * a1.y + s2[k] * a2.y;
    z[k] = c.z + s0[k] * a0.z + s1[k] * a1.z + s2[k] * a2.z;
  }
  const WindowProjection project(cam);
  if (project.perspective) {  // a loop each way, so that each vectorizes
    for (int k = 0; k < 8; ++k) project.from_eye(x[k], y[k], z[k]);
  } else {
    for (int k = 0; k < 8; ++k) {
      x[k] *= project.inv_half;
      y[k] *= project.inv_half;
    }
  }
  float x0 = x[0], x1 = x[0], y0 = y[0], y1 = y[0];
  for (int k = 1; k < 8; ++k) {
    x0 = std::min(x0, x[k]);
    x1 = std::max(x1, x[k]);
    y0 = std::min(y0, y[k]);
    y1 = std::max(y1, y[k]);
  }
  e.lo = glm::min(e.lo, glm::vec2(x0, y0));
  e.hi = glm::max(e.hi, glm::vec2(x1, y1));
}

// Adds the box [lo, hi] placed by the affine `m` (columns: axes and translation; world metres)
// to `e`, its centre (relative to `origin`, the snapshot's centre) and half edges projected once.
void add_placed_box(const SnapshotCamera& cam, const glm::mat4& m, const glm::vec3& lo, const glm::vec3& hi,
                    const glm::vec3& origin, PlaneExtent& e) {
  auto frame = [&cam](const glm::vec3& v) { return glm::vec3(glm::dot(v, cam.ho), glm::dot(v, cam.uo), glm::dot(v, cam.vo)); };
  const glm::vec3 h = 0.5f * (hi - lo);
  add_framed_box(cam, frame(glm::vec3(m * glm::vec4(0.5f * (lo + hi), 1.0f)) - origin), frame(glm::vec3(m[0]) * h.x),
                 frame(glm::vec3(m[1]) * h.y), frame(glm::vec3(m[2]) * h.z), e);
}

// The snapshot camera's frame seen from a character's model space: a model-space point p lies at
// dot(p, f[j]) + k[j] along Ho, Uo, Vo (j = 0, 1, 2) from the snapshot's centre, placed by the
// character's scale, yaw about +Y and position.
struct ModelFrame {
  glm::vec3 f[3];
  glm::vec3 k;
};
ModelFrame model_frame(const SnapshotCamera& cam, const Character& ch) {
  const float cy = std::cos(ch.yaw), sy = std::sin(ch.yaw), sc = ch.scale;
  ModelFrame mf;
  const glm::vec3 axes[3] = {cam.ho, cam.uo, cam.vo};
  for (int j = 0; j < 3; ++j) {
    const glm::vec3& a = axes[j];
    mf.f[j] = sc * glm::vec3(cy * a.x - sy * a.z, a.y, sy * a.x + cy * a.z);  // the transposed placement
    mf.k[j] = glm::dot(ch.position - cam.ta, a);
  }
  return mf;
}

// Adds the box [lo, hi] of a palette entry's space, carried into model space by the entry's
// matrix (its three rows: model = rows * (p, 1)), to `e`: the box's centre and half edges are
// taken into the camera's frame through the rows projected once on each axis.
void add_carried_box(const SnapshotCamera& cam, const ModelFrame& mf, const glm::vec4 (&rows)[3], const glm::vec3& lo,
                     const glm::vec3& hi, PlaneExtent& e) {
  const glm::vec4 mid(0.5f * (lo + hi), 1.0f);
  const glm::vec3 h = 0.5f * (hi - lo);
  glm::vec3 c, a0, a1, a2;
  for (int j = 0; j < 3; ++j) {
    const glm::vec4 g = mf.f[j].x * rows[0] + mf.f[j].y * rows[1] + mf.f[j].z * rows[2];
    c[j] = mf.k[j] + glm::dot(g, mid);
    a0[j] = g.x * h.x;
    a1[j] = g.y * h.y;
    a2[j] = g.z * h.z;
  }
  add_framed_box(cam, c, a0, a1, a2, e);
}

WindowRects window_rects(const PlaneExtent& e, int window_size) {
  const float texel = 2.0f / static_cast<float>(window_size);
  const glm::vec2 t0 = glm::floor(e.lo / texel), t1 = glm::ceil(e.hi / texel);
  return {glm::vec4(glm::clamp((t0 - 1.0f) * texel, -1.0f, 1.0f), glm::clamp((t1 + 1.0f) * texel, -1.0f, 1.0f)),
          glm::vec4(glm::clamp((t0 - 4.0f) * texel, -1.0f, 1.0f), glm::clamp((t1 + 4.0f) * texel, -1.0f, 1.0f))};
}

// How far (texels, whole) beyond a snapshot's covered texels the impostor shader's taps at a pixel
// read them, in a window of `texels_per_pixel`: half a texel for the bilinear filter, and the
// taps' largest offset from the pixel's centre, `tap_offset` pixels (tap_offset_of). A quad fitted
// to the covered texels is widened by it: a pixel is drawn where its centre lies in the quad (in a
// multisampled target, any of its samples: no fewer pixels for quads that face the screen), and
// a pixel whose taps read covered texels has its centre within that reach of them. Until the
// fifty-fourth session the reach also held half a pixel more, whatever the taps: one tap at one
// texel per pixel reached 2 texels instead of 1 (RiggedSimple, 10,000 humans: 19 % more quad
// texels, the same pictures; docs/results.md).
float taps_reach(float texels_per_pixel, float tap_offset) { return std::ceil(0.5f + tap_offset * texels_per_pixel); }

// The impostor shader's farthest tap from a pixel's centre (pixels) for `c`: none for one tap,
// 0.28 for two (at +-(0.2, -0.2)), 0.40 for four (the 4x sample pattern, (0.375, 0.125) at most),
// their distance and not their offset along an axis, as a part card turned by its bone since its
// snapshot lies askew on the screen; per-sample taps lie on samples, which the rasterizer tests
// themselves. Depth-corrected cards keep the older, wider 0.875 (their taps follow the parallax
// steps).
float tap_offset_of(const ImpostorConfig& c) {
  if (c.parallax_cards) return 0.875f;
  return c.impostor_taps <= 1 ? 0.0f : c.impostor_taps == 2 ? std::hypot(0.2f, 0.2f) : std::hypot(0.375f, 0.125f);
}

// What the GPU needs to draw one snapshot of `instance` with `cam` (its window centred on cam.ta,
// the subject a sphere of `radius` metres) into `win` of a `page`-pixel atlas page, clearing `rect`
// of the window.
// `quad` is the part of the window the impostor's quad shows; `slot` its fitted rectangle's index,
// found when `fit`, widened by `reach` texels (taps_reach at the window's texels per screen pixel
// at the subject's depth; tighter margins drop coverage: tests).
SnapshotGpu snapshot_gpu(const InstanceGpu& instance, const SnapshotCamera& cam, float radius, const AtlasWindow& win,
                         float page, const glm::vec4& rect, const glm::vec4& quad, int slot, bool fit, float reach) {
  SnapshotGpu s;
  s.instance = instance;
  s.ho_half = glm::vec4(cam.ho, cam.half_size);
  s.uo_dist = glm::vec4(cam.uo, cam.distance);
  s.vo = glm::vec4(cam.vo, cam.perspective ? 1.0f : 0.0f);
  s.ta = glm::vec4(cam.ta, radius);
  s.offset = glm::vec4(cam.offset, 0.0f, 0.0f);
  const float half = static_cast<float>(win.size) / page;  // NDC half extent = size / page
  s.window = glm::vec4(-1.0f + (2.0f * win.x + win.size) / page, -1.0f + (2.0f * win.y + win.size) / page, half,
                       static_cast<float>(win.page));
  s.rect = rect;
  s.quad = quad;
  s.part.y = static_cast<float>(slot);
  s.part.z = fit ? 1.0f : 0.0f;
  s.part.w = reach;
  return s;
}

// Palette entry `entry`'s matrix (model space) between baked frames f0 and f1 of `bc`.
glm::mat4 palette_matrix(std::span<const glm::vec4> pal, int entries, const BakedClip& bc, int f0, int f1, float blend,
                         int entry) {
  const glm::vec4* a = &pal[((bc.first_row + f0) * static_cast<std::size_t>(entries) + entry) * 3];
  const glm::vec4* b = &pal[((bc.first_row + f1) * static_cast<std::size_t>(entries) + entry) * 3];
  glm::mat4 pm(1.0f);
  for (int r = 0; r < 3; ++r) {
    const glm::vec4 row = a[r] + (b[r] - a[r]) * blend;
    for (int c = 0; c < 4; ++c) pm[c][r] = row[c];
  }
  return pm;
}

// The rows of palette entry `entry`'s matrix (model = rows * (p, 1)) between the baked palette's
// rows `row0` and `row1` (absolute: InstanceGpu::anim's y and z).
inline void palette_rows_at(std::span<const glm::vec4> pal, int entries, int row0, int row1, float blend, int entry,
                            glm::vec4 (&rows)[3]) {
  const glm::vec4* a = &pal[(static_cast<std::size_t>(row0) * entries + entry) * 3];
  const glm::vec4* b = &pal[(static_cast<std::size_t>(row1) * entries + entry) * 3];
  for (int r = 0; r < 3; ++r) rows[r] = a[r] + (b[r] - a[r]) * blend;
}

// The same between baked frames f0 and f1 of `bc`.
void palette_rows(std::span<const glm::vec4> pal, int entries, const BakedClip& bc, int f0, int f1, float blend, int entry,
                  glm::vec4 (&rows)[3]) {
  palette_rows_at(pal, entries, bc.first_row + f0, bc.first_row + f1, blend, entry, rows);
}

// Model space -> world for character `ch` (scale, yaw about +Y, position).
glm::mat4 placement(const Character& ch) {
  const float cy = std::cos(ch.yaw), sy = std::sin(ch.yaw), sc = ch.scale;
  return glm::mat4(glm::vec4(cy * sc, 0, -sy * sc, 0), glm::vec4(0, sc, 0, 0), glm::vec4(sy * sc, 0, cy * sc, 0),
                   glm::vec4(ch.position, 1));
}

// Rects in window units as (x0, y0, x1, y1): their overlap.
glm::vec4 rect_intersection(const glm::vec4& a, const glm::vec4& b) {
  return glm::vec4(glm::max(glm::vec2(a), glm::vec2(b)), glm::min(glm::vec2(a.z, a.w), glm::vec2(b.z, b.w)));
}

// The extent, in a snapshot camera's window units, of a character's vertices skinned as the
// snapshot shader skins them (ImpostorConfig::fit_quads_from_vertices): that of the snapshot's
// triangles, so of every texel they cover. Each palette entry's rows (between the baked palette's
// rows `row0` and `row1`) are projected once on the camera's axes, placed by `mf`.
class SkinnedExtent {
 public:
  SkinnedExtent(const SnapshotCamera& cam, const ModelFrame& mf, std::span<const glm::vec4> pal, int entries, int row0,
                int row1, float blend)
      : project_(cam), mf_(mf) {
    g_.resize(static_cast<std::size_t>(entries) * 3);
    rows_ = g_.data();
    for (int k = 0; k < entries; ++k) {
      glm::vec4 rows[3];
      palette_rows_at(pal, entries, row0, row1, blend, k, rows);
      for (int j = 0; j < 3; ++j) g_[static_cast<std::size_t>(k) * 3 + j] = mf.f[j].x * rows[0] + mf.f[j].y * rows[1] + mf.f[j].z * rows[2];
    }
    if (++call_ == 0) {  // wrapped: forget every mark
      std::fill(seen_.begin(), seen_.end(), 0u);
      call_ = 1;
    }
  }
  void add(const Vertex& v) {
    glm::vec4 a(0.0f), b(0.0f), c(0.0f);
    for (int k = 0; k < 4; ++k) {
      const float w = v.weights[k];
      if (w <= 0.0f) continue;
      const glm::vec4* gk = rows_ + static_cast<std::size_t>(v.joints[k]) * 3;
      a += w * gk[0];
      b += w * gk[1];
      c += w * gk[2];
    }
    const glm::vec4 p(v.position, 1.0f);
    const glm::vec2 w = project_(mf_.k[0] + glm::dot(a, p), mf_.k[1] + glm::dot(b, p), mf_.k[2] + glm::dot(c, p));
    extent.lo = glm::min(extent.lo, w);
    extent.hi = glm::max(extent.hi, w);
  }
  // The vertices of `ml` that `indices` names, each once over this object's life (triangles share them).
  void add_once(const MeshLod& ml, std::span<const std::uint32_t> indices) {
    if (seen_.size() < ml.vertices.size()) seen_.resize(ml.vertices.size(), 0);
    for (std::uint32_t i : indices)
      if (seen_[i] != call_) {
        seen_[i] = call_;
        add(ml.vertices[i]);
      }
  }
  // Shrinks the quad and the cleared rect of a snapshot in a `window_size` window to the extent's
  // texels (false where nothing was added): the quad widened by the taps' `reach` (texels,
  // taps_reach), as the coverage pass widens its rectangle, and the cleared rect by that reach
  // again and a texel, so that no tap of a pixel in the quad reads a texel an earlier snapshot left.
  bool fit(int window_size, float reach, glm::vec4& quad, glm::vec4& cleared) const {
    if (!(extent.lo.x <= extent.hi.x)) return false;
    const float texel = 2.0f / static_cast<float>(window_size);
    const glm::vec2 t0 = glm::floor(extent.lo / texel), t1 = glm::ceil(extent.hi / texel);
    auto widened = [&](float m) {
      return glm::vec4(glm::clamp((t0 - m) * texel, -1.0f, 1.0f), glm::clamp((t1 + m) * texel, -1.0f, 1.0f));
    };
    quad = rect_intersection(quad, widened(reach));
    cleared = rect_intersection(cleared, widened(2.0f * reach + 1.0f));
    return true;
  }
  PlaneExtent extent;

 private:
  WindowProjection project_;
  const ModelFrame& mf_;
  const glm::vec4* rows_ = nullptr;  // g_'s
  static thread_local std::vector<glm::vec4> g_;  // per palette entry: its rows projected on Ho, Uo, Vo
  static thread_local std::vector<std::uint32_t> seen_;  // per vertex: the object that took it
  static thread_local std::uint32_t call_;
};
thread_local std::vector<glm::vec4> SkinnedExtent::g_;
thread_local std::vector<std::uint32_t> SkinnedExtent::seen_;
thread_local std::uint32_t SkinnedExtent::call_ = 0;

// The posture distances (squared, model space) between baked frames f0 and f1 of `bc`.
std::array<float, 4> posture_at(const BakedClip& bc, int f0, int f1, float blend) {
  std::array<float, 4> p;
  for (int k = 0; k < 4; ++k) p[k] = bc.posture[f0][k] + (bc.posture[f1][k] - bc.posture[f0][k]) * blend;
  return p;
}

// The refresh budget's share-out (the paper's section 7, item 1): moves the `budget_left` stalest
// of `pending` (ties to the lower index, so the choice does not depend on the sort) to its front
// and returns how many that is (`order`: the record's index, character then part).
template <typename Pending>
std::size_t stalest_first(std::vector<Pending>& pending, int budget_left) {
  const std::size_t take = static_cast<std::size_t>(std::clamp(budget_left, 0, static_cast<int>(pending.size())));
  auto staler = [](const Pending& a, const Pending& b) {
    return a.staleness != b.staleness ? a.staleness > b.staleness : a.order < b.order;
  };
  if (take < pending.size()) std::nth_element(pending.begin(), pending.begin() + take, pending.end(), staler);
  return take;
}

// Area of `rect` (window units, [-1, 1]^2) in texels of a `size`-texel window.
float rect_texels(const glm::vec4& rect, int size) {
  const float h = 0.5f * static_cast<float>(size);
  return (rect.z - rect.x) * h * (rect.w - rect.y) * h;
}

// The impostor of a character whose Ta is at `ta` now and whose scale is `grow` times its scale at
// its cached snapshot `cs` (the picture scaled about Ta): a quad facing the eye, or (aligned
// snapshots) parallel to the screen, whose axes are the camera's `right` and `up`.
template <typename State>
BillboardGpu billboard(const glm::vec3& ta, const State& cs, float grow, float page, int slot, const glm::vec3& right,
                       const glm::vec3& up) {
  const AtlasWindow& win = cs.window;
  const float half = cs.half_size * grow;
  BillboardGpu b{glm::vec4(ta, half),
                 glm::vec4(win.x / page, win.y / page, (win.x + win.size) / page, (win.y + win.size) / page),
                 glm::vec4(static_cast<float>(win.page), static_cast<float>(slot), cs.fitted ? 1.0f : 0.0f, 0.0f),
                 cs.rect};
  if (cs.aligned) {
    b.ta_half = glm::vec4(ta + grow * (cs.offset.x * right + cs.offset.y * up), half);
    b.axis_x = glm::vec4(right * half, 1.0f);
    b.axis_y = glm::vec4(up * half, 1.0f);
  }
  return b;
}

// A snapshot cut at a scale (aligned, texel_per_pixel) seen this many times larger is taken anew.
constexpr float kMagnifiedRefresh = 1.5f;

// Window texels per screen pixel for a `window_size`-texel window spanning 2 `half_size` metres at
// `depth` metres from the eye (`ppm1`: the camera's pixels per metre at depth 1).
float window_texels_per_pixel(int window_size, float half_size, float depth, float ppm1) {
  return static_cast<float>(window_size) * std::max(depth, 1e-3f) / (2.0f * half_size * ppm1);
}

// The inverse: the half size (metres) at which a `window_size`-texel window `depth` metres from the
// eye holds `texels_per_pixel` texels per screen pixel (ImpostorConfig::texel_per_pixel).
float half_size_at(int window_size, float texels_per_pixel, float depth, float ppm1) {
  return static_cast<float>(window_size) * depth / (2.0f * ppm1 * std::max(texels_per_pixel, 1e-3f));
}

// How far past the posture threshold: the largest relative change of the four squared
// distances over `threshold` (as posture_changed, whose test is this > 1).
float posture_staleness(const std::array<float, 4>& stored, const std::array<float, 4>& now, float threshold) {
  float worst = 0.0f;
  for (int k = 0; k < 4; ++k) {
    const float ref = stored[k] > 0.0f ? stored[k] : 1.0f;
    worst = std::max(worst, std::abs(now[k] - stored[k]) / ref);
  }
  return worst / std::max(threshold, 1e-6f);
}

// Adds the counts of `b` (a chunk of the crowd) to `a`.
void add_stats(FrameStats& a, const FrameStats& b) {
  a.culled += b.culled;
  a.geometry += b.geometry;
  a.impostors += b.impostors;
  a.snapshots += b.snapshots;
  a.part_cards += b.part_cards;
  a.part_snapshots += b.part_snapshots;
  a.atlas_fallbacks += b.atlas_fallbacks;
  a.posture_refreshes += b.posture_refreshes;
  a.view_refreshes += b.view_refreshes;
  a.window_refreshes += b.window_refreshes;
  a.new_snapshots += b.new_snapshots;
  a.deferred_refreshes += b.deferred_refreshes;
  a.short_lived_geometry += b.short_lived_geometry;
  a.lead_snapshots += b.lead_snapshots;
  for (std::size_t k = 0; k < a.geometry_per_lod.size(); ++k) a.geometry_per_lod[k] += b.geometry_per_lod[k];
  for (std::size_t k = 0; k < a.impostors_per_window.size(); ++k) a.impostors_per_window[k] += b.impostors_per_window[k];
  a.geometry_triangles += b.geometry_triangles;
  a.snapshot_triangles += b.snapshot_triangles;
  a.quad_texels += b.quad_texels;
}

// Character `ch`'s clip and the baked frames around its clip time at scene time `time`.
struct BakedFrames {
  int clip = 0, f0 = 0, f1 = 0;
  float blend = 0.0f;  // f0 -> f1
};
// The screen's right and up axes in the frame of the line of sight from `eye` to `ta` (section 4.2's
// Ho, Uo, Vo, with the world's up; Z looking straight down): what an aligned snapshot was cut along,
// as its view test compares them (a camera turned or rolled in place turns them, and no line of
// sight in the character's frame).
struct ScreenAxes {
  glm::vec3 right, up;
};
ScreenAxes screen_axes_in_sight(const glm::vec3& ta, const glm::vec3& eye, const glm::vec3& right, const glm::vec3& up) {
  const glm::vec3 vo = ta - eye;
  glm::vec3 ho = glm::cross(vo, glm::vec3(0.0f, 1.0f, 0.0f));
  if (glm::dot(ho, ho) < 1e-12f * glm::dot(vo, vo)) ho = glm::cross(vo, glm::vec3(0.0f, 0.0f, 1.0f));
  if (!(glm::dot(ho, ho) > 0.0f)) return {right, up};
  const glm::vec3 v = glm::normalize(vo), h = glm::normalize(ho), u = glm::cross(h, v);
  return {glm::vec3(glm::dot(right, h), glm::dot(right, u), glm::dot(right, v)),
          glm::vec3(glm::dot(up, h), glm::dot(up, u), glm::dot(up, v))};
}

BakedFrames baked_frames(const Model& m, const Character& ch, float time) {
  BakedFrames b;
  b.clip = m.clips.empty() ? 0 : std::clamp(ch.clip, 0, static_cast<int>(m.clips.size()) - 1);
  const BakedClip& bc = m.baked_clips()[b.clip];
  const BakedSample s = bc.sample(clip_time(ch.phase + ch.speed * time, m.clip_duration(b.clip), true));
  b.f0 = s.f0;
  b.f1 = s.f1;
  b.blend = s.blend;
  return b;
}

}  // namespace

void FramePlanner::Chunk::clear(std::size_t lods, std::size_t characters, std::size_t cards) {
  geometry.resize(lods);
  for (auto& g : geometry) {
    g.clear();
    g.reserve(characters);
  }
  snapshots.clear();
  snapshots.reserve(cards);
  snapshot_lods.clear();
  snapshot_lods.reserve(cards);
  billboards.clear();
  billboards.reserve(cards);
  pending.clear();
  pending.reserve(characters);
  ahead.clear();
  ahead.reserve(characters);
  deferred.clear();
  deferred.reserve(characters);
  pending_parts.clear();
  part_jobs.clear();
  st = FrameStats{};
  budget_used = 0;
}

unsigned FramePlanner::planner_threads() {
  unsigned want = config_.planner_threads;
  if (want == 0) want = std::max(1u, std::thread::hardware_concurrency());
  if (want > 1 && (!pool_ || pool_->size() != want)) pool_ = WorkerPool::shared(want);
  return want;
}

glm::vec3 character_ta(const Model& m, const Character& ch, float time) {
  const auto [clip, f0, f1, blend] = baked_frames(m, ch, time);
  const BakedClip& bc = m.baked_clips()[clip];
  const glm::vec2 travel = bc.root_offset[f0] + (bc.root_offset[f1] - bc.root_offset[f0]) * blend;
  const glm::vec3 l = (m.ta + glm::vec3(travel.x, 0.0f, travel.y)) * ch.scale;
  const float cy = std::cos(ch.yaw), sy = std::sin(ch.yaw);
  return ch.position + glm::vec3(cy * l.x + sy * l.z, l.y, -sy * l.x + cy * l.z);
}

Status validate_impostor_config(const ImpostorConfig& c) {
  auto bad = [](const char* setting, std::string reason) { return Error{"", std::string("ImpostorConfig::") + setting, std::move(reason)}; };
  const WindowSizes& w = c.windows;
  if (w.count < 1 || w.count > static_cast<int>(w.size.size()))
    return bad("windows", "count " + std::to_string(w.count) + " is not in [1, " + std::to_string(w.size.size()) + "]");
  for (int k = 0; k < w.count; ++k) {
    if (w.size[k] < 1)
      return bad("windows", "size[" + std::to_string(k) + "] is " + std::to_string(w.size[k]) + ": a window has a pixel at least");
    if (k > 0 && w.size[k] > w.size[k - 1])
      return bad("windows", "size[" + std::to_string(k) + "] (" + std::to_string(w.size[k]) + ") is larger than size[" +
                                std::to_string(k - 1) + "] (" + std::to_string(w.size[k - 1]) + "): sizes go largest first");
  }
  if (c.page_size < w.size[0])
    return bad("page_size", std::to_string(c.page_size) + " is smaller than the largest window (" + std::to_string(w.size[0]) +
                                " pixels): an atlas page must hold a window of every size");
  if (c.max_pages < 1) return bad("max_pages", std::to_string(c.max_pages) + ": the atlas needs a page at least");
  if (c.first_page < 0) return bad("first_page", std::to_string(c.first_page) + " is negative");
  if (c.atlas_pages != 0 && c.first_page + c.max_pages > c.atlas_pages)
    return bad("atlas_pages", "pages " + std::to_string(c.first_page) + " to " + std::to_string(c.first_page + c.max_pages - 1) +
                                  " do not lie in an atlas of " + std::to_string(c.atlas_pages) + " pages");
  if (!(c.texels_per_pixel > 0.0f) || !std::isfinite(c.texels_per_pixel))
    return bad("texels_per_pixel", std::to_string(c.texels_per_pixel) + ": texels per pixel must be finite and > 0");
  if (!(c.aligned_phase >= 0.0f && c.aligned_phase < 1.0f))
    return bad("aligned_phase", std::to_string(c.aligned_phase) + " is not in [0, 1) pixels");
  if (c.quad_fetch < 0 || c.quad_fetch > 2)
    return bad("quad_fetch", std::to_string(c.quad_fetch) + " is not 0 (auto), 1 (instanced) or 2 (pulled)");
  return Ok{};
}

namespace {
std::atomic<std::uint64_t> g_next_cache{1};  // FramePlanner::cache_id_: unique in the process
}  // namespace

FramePlanner::FramePlanner(const Model& model, const ImpostorConfig& config)
    : model_(&model), config_(config), atlas_(config.page_size, config.max_pages, config.windows, config.first_page),
      cache_id_(g_next_cache.fetch_add(1, std::memory_order_relaxed)) {
  assert(validate_impostor_config(config).ok() && "ImpostorConfig breaks a contract: validate_impostor_config says which");
  config_.windows.count = std::clamp(config_.windows.count, 1, static_cast<int>(config_.windows.size.size()));
  plan_.geometry.resize(model.lods.size());
  plan_.snapshots.resize(model.lods.size());
}

void FramePlanner::invalidate() {
  for (auto& c : cache_) c.valid = false;
  cache_id_ = g_next_cache.fetch_add(1, std::memory_order_relaxed);
  cache_plans_ = 0;
}

int FramePlanner::coverage_slot_of(const AtlasWindow& w) const {
  return coverage_slot(w, atlas_.page_size(), config_.windows.size[config_.windows.count - 1]);
}

int FramePlanner::lod_for(float pixels, int viewport_height) const {
  const float coverage = pixels / static_cast<float>(std::max(1, viewport_height));
  const int n = static_cast<int>(model_->lods.size());
  for (int l = 0; l < n - 1; ++l)
    if (coverage >= model_->lods[l].screen_coverage) return l;
  return n - 1;
}

void FramePlanner::plan_character(std::size_t i, const Character& ch, const FrameSetup& fs, const Out& out) {
  const Model& m = *model_;
  const SceneCamera& camera = fs.camera;
  const auto& planes = fs.planes;
  const glm::vec3 &cam_right = fs.cam_right, &cam_up = fs.cam_up, &fwd = fs.fwd;
  const float ppm1 = fs.ppm1, cos_view = fs.cos_view, switch_px = fs.switch_px, page = fs.page, time = fs.time;
  const bool impostor_mode = fs.impostor_mode, budget = fs.budget;
  const RenderMode mode = fs.mode;
  const CacheConfig& cc = config_.cache;
  const auto baked = m.baked_clips();
  const auto parts = m.body_parts();
  const auto pal = m.baked_palette();
  const int np = static_cast<int>(m.palette.size());
  const int lods = static_cast<int>(m.lods.size());
  const auto& window_lod = fs.window_lod;
  FrameStats& st = *out.st;
  const float radius = m.radius * ch.scale;
  const float cy = std::cos(ch.yaw), sy = std::sin(ch.yaw);
  // Animation state: baked frames around the character's clip time.
  const auto [clip, f0, f1, blend] = baked_frames(m, ch, time);
  const BakedClip& bc = baked[clip];
  const glm::vec2 travel = bc.root_offset[f0] + (bc.root_offset[f1] - bc.root_offset[f0]) * blend;
  const glm::vec3 ta_local = (m.ta + glm::vec3(travel.x, 0.0f, travel.y)) * ch.scale;
  const glm::vec3 ta = ch.position + glm::vec3(cy * ta_local.x + sy * ta_local.z, ta_local.y, -sy * ta_local.x + cy * ta_local.z);
  bool outside = false;
  for (const auto& p : planes) outside |= glm::dot(glm::vec3(p), ta) + p.w < -radius;
  // A character placed nowhere (a position, yaw or scale not finite) is tested against no plane
  // (every comparison with NaN is false): culled, so that it takes no window.
  outside |= !std::isfinite(ta.x) || !std::isfinite(ta.y) || !std::isfinite(ta.z) || !std::isfinite(radius);
  if (outside) {
    ++st.culled;
    return;
  }
  InstanceGpu inst{glm::vec4(ch.position, ch.yaw),
                   glm::vec4(ch.scale, static_cast<float>(bc.first_row + f0), static_cast<float>(bc.first_row + f1), blend)};
  const float depth = glm::dot(ta - camera.eye, fwd);
  const float pixels = 2.0f * radius * ppm1 / std::max(depth, 1e-3f);

  // Drawn as skinned geometry, at the level the geometry path picks for its size on screen.
  auto draw_geometry = [&] {
    const int lod = std::min(lod_for(pixels, camera.height), lods - 1);
    (*out.geometry)[lod].push_back(inst);
    ++st.geometry;
    ++st.geometry_per_lod[std::min(lod, 7)];
    st.geometry_triangles += m.lods[lod].triangle_count();
  };
  bool as_geometry = !impostor_mode || (mode == RenderMode::kAuto && pixels > switch_px);
  if (!as_geometry && parts_ > 1) {
    const PartsPlanned planned = plan_parts(i, ch, bc, f0, f1, blend, inst, ta, radius, pixels, camera, time, out);
    if (planned == PartsPlanned::kDeferred) return;
    as_geometry = planned == PartsPlanned::kGeometry;
  } else if (!as_geometry) {
    CacheState& cs = cache_[i];
    // Aligned snapshots hold the sphere's whole picture (wider off the axis) at the exact scale.
    float need = pixels;
    if (config_.aligned_snapshots) {
      const float a = aligned_pixels(camera.eye, cam_right, cam_up, fwd, ppm1, ta, radius);
      if (std::isfinite(a)) need = a;
    }
    const int wclass = choose_window(config_.windows, need * config_.texels_per_pixel);
    if (out.deferred && (!cs.window.valid() || cs.window.size_class != wclass)) {
      out.deferred->push_back(static_cast<std::uint32_t>(i));  // the atlas is served in order, after
      return;
    }
    bool refresh = !cs.valid;
    // (Without a window, a valid state is a starved character's planned again: its change of window
    // was counted when its window was released.)
    if (!refresh && cs.window.valid() && cs.window.size_class != wclass) {
      refresh = true;
      ++st.window_refreshes;
    }
    if (cs.window.valid() && cs.window.size_class != wclass) {
      atlas_.release(cs.window);
      cs.window = AtlasWindow{};
    }
    if (!cs.window.valid()) {
      auto w = atlas_.allocate(wclass);
      if (!w && out.starved) {  // planned again at the end of the frame, when windows may be taken back
        out.starved->push_back(static_cast<std::uint32_t>(i));
        return;
      }
      if (!w && out.reclaim) w = allocate_or_reclaim(wclass, true);
      if (!w) {
        ++st.atlas_fallbacks;
        cs.valid = false;
        as_geometry = true;
      } else {
        cs.window = *w;
        refresh = true;
      }
    }
    if (!as_geometry) {
      cs.drawn = fs.frame;  // its window is in use this frame
      auto snapshot_camera = [&](const glm::vec3& eye, const glm::vec3& up) {
        SnapshotCamera c = make_snapshot_camera(ta, eye, up, radius,
                                                config_.snapshot_distance > 0 ? config_.snapshot_distance * ch.scale : 0.0f,
                                                config_.perspective_snapshots);
        if (config_.texel_per_pixel && c.perspective)
          c.half_size = std::max(c.half_size, half_size_at(config_.windows.size[wclass], config_.texels_per_pixel, c.distance, ppm1));
        return c;
      };
      SnapshotCamera sc = snapshot_camera(camera.eye, camera.up);
      // The view test's frame is section 4.2's (the line of sight to Ta) in either case.
      const glm::mat3 view = view_rotation(sc, ch.yaw);
      // Leading whole impostors (ImpostorConfig::view_lead): the eye in the character's frame, and
      // its velocity there since the previous planned frame (kept when the character is planned
      // again in the same frame, as a refresh budget does), for a refresh to lead by.
      if (config_.view_lead > 0.0f && cc.view_test && (time != cs.eye_time || !cs.eye_valid)) {
        const glm::vec3 e = glm::vec3(cy * (camera.eye.x - ta.x) - sy * (camera.eye.z - ta.z), camera.eye.y - ta.y,
                                      sy * (camera.eye.x - ta.x) + cy * (camera.eye.z - ta.z));
        const bool later = cs.eye_valid && time > cs.eye_time;
        cs.eye_vel = later ? (e - cs.eye_char) / (time - cs.eye_time) : glm::vec3(0.0f);
        cs.eye_step = later ? time - cs.eye_time : 0.0f;
        cs.eye_char = e;
        cs.eye_time = time;
        cs.eye_valid = true;
      }

      // Posture distances of the current frame (squared, model space, scaled).
      const std::array<float, 4> posture = posture_at(bc, f0, f1, blend);
      bool must = refresh;  // no usable snapshot: refreshed whatever the budget
      float staleness = 0.0f;
      // Both thresholds' weight, and the view threshold (radians) it gives.
      const float w = distance_weight(cc, glm::distance(ta, camera.eye), pixels);
      const float thr = std::min(glm::radians(cc.view_threshold_deg) * w, 3.14159265f);
      if (!refresh) {
        float ahead = 0.0f;  // staleness of a fresh one, where it may be refreshed ahead
        if (cc.view_test) {
          const float cthr = w == 1.0f ? cos_view : std::cos(thr);
          const float c = rotation_cosine(cs.view, view);
          // A threshold of 0 refreshes on any turn: a slow turn's cosine rounds to 1 in floats.
          // An aligned snapshot was cut on the screen of its moment and its quad is drawn on
          // today's: where the screen has turned about the line of sight's frame (a camera turned
          // or rolled in place, which turns no line of sight in the character's frame) it is
          // tested as well. Measured on the flow test bed: still and orbiting cameras refresh as
          // before (the character's frame turns first); CesiumMan orbited at 30 degrees/s, poses
          // held, 8 degrees: the quad along the old screen's axes instead 15.5 dB, along today's
          // 16.8, today's with a test of the axes' own turn in the world 17.1 dB at 20 % more
          // refreshes.
          // The cosine of the turn between the two frames: (trace - 1) / 2 of the rotation.
          float ca = 1.0f;
          bool turned = false;
          if (cs.aligned) {
            const ScreenAxes a = screen_axes_in_sight(ta, camera.eye, cam_right, cam_up);
            ca = 0.5f * (glm::dot(cs.screen_right, a.right) + glm::dot(cs.screen_up, a.up) +
                         glm::dot(glm::cross(cs.screen_right, cs.screen_up), glm::cross(a.right, a.up)) - 1.0f);
            turned = ca < cthr || (thr <= 0.0f && (cs.screen_right != a.right || cs.screen_up != a.up));
          }
          if (c < cthr || (thr <= 0.0f && cs.view != view) || turned) {
            refresh = true;
            ++st.view_refreshes;
            if (budget) staleness = std::acos(std::clamp(std::min(c, ca), -1.0f, 1.0f)) / std::max(thr, 1e-6f);
          } else if (fs.ahead && thr > 0.0f && !cs.led &&
                     c < (w == 1.0f ? fs.cos_ahead : std::cos(thr * cc.ahead_fraction))) {
            // (A leading snapshot starts off its view: how far it is from it says nothing of
            // how long it has left, so only its posture may refresh it ahead.)
            ahead = std::acos(std::clamp(c, -1.0f, 1.0f)) / thr;
          }
        }
        // Magnified: a snapshot cut at a scale (aligned, or texel_per_pixel) seen larger since, by
        // a zoom or a walk towards the eye that left its window's size class alone (up to twice as
        // large), shows its texels blurred: refreshed past kMagnifiedRefresh. (The audit's probe: a
        // 1.9x zoom kept 34.1 dB where a fresh snapshot gives 38.8.)
        if (!refresh && (cs.aligned || config_.texel_per_pixel)) {
          const float ta_depth = glm::dot(ta - camera.eye, fwd);
          const float tpp = window_texels_per_pixel(cs.window.size, cs.half_size * ch.scale / cs.scale, ta_depth, ppm1);
          if (ta_depth > 0.0f && tpp * kMagnifiedRefresh < config_.texels_per_pixel) {
            refresh = true;
            ++st.window_refreshes;
            if (budget) staleness = std::max(staleness, config_.texels_per_pixel / (tpp * kMagnifiedRefresh));
          }
        }
        if (cc.posture_test && (budget || !refresh) && posture_changed(cs.posture, posture, cc.posture_threshold * w)) {
          if (!refresh) ++st.posture_refreshes;
          refresh = true;
          if (budget) staleness = std::max(staleness, posture_staleness(cs.posture, posture, cc.posture_threshold * w));
        } else if (fs.ahead && !refresh && cc.posture_test && cc.posture_threshold > 0.0f) {
          ahead = std::max(ahead, posture_staleness(cs.posture, posture, cc.posture_threshold * w));
        }
        if (!refresh && out.ahead && ahead >= cc.ahead_fraction)
          out.ahead->push_back(PendingRefresh{ahead, static_cast<std::uint32_t>(i),
                                              static_cast<std::uint32_t>(out.billboards->size())});
        if (out.ahead_now) refresh = true;
      } else if (!cs.valid) {
        ++st.new_snapshots;
      }
      if (config_.short_lived_as_geometry && refresh && !must && !budget && !out.ahead_now && cs.taken + 1 == fs.frame) {
        // Geometry when its last snapshot is stale one frame on, and so on while the posture or
        // the view changes past the thresholds from each frame to the next (the cached state
        // moves on every frame); a snapshot at the first frame where neither does. Leaving it at
        // half the thresholds instead (hysteresis, so that fewer snapshots live one frame) was
        // slower: flow test bed, --msaa 1, posture 0.1, 40 frames, impostor frame 5.06-5.10 ms
        // without, 5.98 ms with, 5.25-5.28 ms with every refresh a snapshot.
        cs.view = view;
        const ScreenAxes a = screen_axes_in_sight(ta, camera.eye, cam_right, cam_up);
        cs.screen_right = a.right;
        cs.screen_up = a.up;
        cs.led = false;
        cs.posture = posture;
        cs.taken = fs.frame;
        cs.picture_behind = true;
        ++st.short_lived_geometry;
        draw_geometry();
        return;
      }
      if (cs.picture_behind) refresh = must = true;  // its window holds an older picture
      const AtlasWindow& win = cs.window;
      const int slot = coverage_slot_of(win);
      if (refresh && !must && budget && !out.forced) {
        // Stale: drawn from its old snapshot unless the budget reaches it. Its refresh is worked
        // out only then (end_frame plans it again, forced): most stale impostors wait.
        out.pending->push_back(PendingRefresh{staleness, static_cast<std::uint32_t>(i),
                                              static_cast<std::uint32_t>(out.billboards->size())});
      } else if (refresh) {
        // The camera the snapshot is taken with: the scene's, or with a lead the scene's turned
        // rigidly about Ta's vertical by the lead (Ta keeps its pixel, its distance and its depth).
        SceneCamera shot = camera;
        glm::vec3 shot_right = cam_right, shot_up = cam_up;
        glm::mat3 shot_view = view;
        float lead_angle = 0.0f, azimuth_rate = 0.0f;
        if (config_.view_lead > 0.0f && cc.view_test) {
          // How fast the eye goes round Ta's vertical (radians of azimuth per second): the view
          // test's frame turns about the vertical by as much. A turn about the vertical keeps the
          // picture upright; a turn about the line of sight's own axis of motion would roll it
          // (camera 25 degrees above, 4 degrees ahead: about 1.7 degrees). Not from (nearly)
          // overhead, where the azimuth spins.
          const glm::vec3 &e = cs.eye_char, &v = cs.eye_vel;
          const float h2 = e.x * e.x + e.z * e.z;
          if (h2 > 0.01f * glm::dot(e, e)) {
            azimuth_rate = (e.z * v.x - e.x * v.z) / h2;
            const float rate = std::abs(azimuth_rate);
            // The lead, at most two frames' turn short of the threshold: a lead of the whole
            // threshold would be due again at the next frame wherever the turn is a little off
            // the one foreseen (flow test bed, 8 degrees, poses held, view_lead 1: refresh
            // fraction 0.033 with the margin, 0.030 without, so it costs little).
            lead_angle = std::min({config_.view_lead * thr, thr - 2.0f * rate * cs.eye_step, rate * kLeadTimeMax});
          }
        }
        if (lead_angle > 0.0f) {  // as a turn of the azimuth about Ta's vertical
          const float azimuth = std::copysign(lead_angle, azimuth_rate);
          const glm::mat3 turn = glm::mat3(glm::rotate(glm::mat4(1.0f), azimuth, glm::vec3(0.0f, 1.0f, 0.0f)));
          shot.eye = ta + turn * (camera.eye - ta);
          shot.target = ta + turn * (camera.target - ta);
          shot.up = turn * camera.up;
          shot_right = turn * cam_right;
          shot_up = turn * cam_up;
          sc = snapshot_camera(shot.eye, shot.up);
          shot_view = view_rotation(sc, ch.yaw);
          ++st.lead_snapshots;
        }
        std::optional<SnapshotCamera> aligned;
        if (config_.aligned_snapshots)
          aligned = make_aligned_snapshot_camera(shot, ta, radius, win.size, config_.texels_per_pixel, config_.aligned_phase);
        if (aligned) sc = *aligned;
        CacheState next = cs;
        next.valid = true;
        next.view = shot_view;
        next.led = lead_angle > 0.0f;
        next.posture = posture;
        next.half_size = sc.half_size;
        next.scale = ch.scale;
        next.aligned = aligned.has_value();
        next.fitted = fit_quad(cs.valid && !cs.picture_behind ? cs.taken : 0, fs.frame);
        next.picture_behind = false;
        next.taken = fs.frame;
        next.offset = glm::vec2(glm::dot(sc.ta - ta, shot_right), glm::dot(sc.ta - ta, shot_up));
        // (A lead turns the eye and the axes alike about Ta: the same axes.)
        const ScreenAxes a = screen_axes_in_sight(ta, camera.eye, cam_right, cam_up);
        next.screen_right = a.right;
        next.screen_up = a.up;
        next.rect = glm::vec4(-1, -1, 1, 1);
        glm::vec4 snap_rect = next.rect;
        if (config_.tight_quads) {
          // This frame's pose box.
          const auto& b0 = bc.bounds[f0];
          const auto& b1 = bc.bounds[f1];
          const glm::vec3 lo = glm::min(b0[0], b1[0]), hi = glm::max(b0[1], b1[1]);  // model space
          const ModelFrame mf = model_frame(sc, ch);
          static constexpr glm::vec4 kIdentityRows[3] = {glm::vec4(1, 0, 0, 0), glm::vec4(0, 1, 0, 0), glm::vec4(0, 0, 1, 0)};
          PlaneExtent pose;
          add_carried_box(sc, mf, kIdentityRows, lo, hi, pose);
          WindowRects r = window_rects(pose, win.size);
          if (parts.size() > 1) {
            // Tighter: the union of the body parts' boxes, each carried by its bone (a limb's
            // box lies along the limb), within the pose's box.
            PlaneExtent union_of_parts;
            glm::vec4 rows[3];
            for (const BodyPart& bp : parts) {
              palette_rows(pal, np, bc, f0, f1, blend, bp.bone, rows);
              add_carried_box(sc, mf, rows, bp.box_min, bp.box_max, union_of_parts);
            }
            const WindowRects rr = window_rects(union_of_parts, win.size);
            r.quad = rect_intersection(r.quad, rr.quad);
            r.snapshot = rect_intersection(r.snapshot, rr.snapshot);
          }
          next.rect = r.quad;
          snap_rect = r.snapshot;
        }
        const int slod = config_.snapshot_lod_from_screen ? std::min(lod_for(pixels, camera.height), lods - 1)
                                                          : window_lod[win.size_class];
        const float reach = taps_reach(window_texels_per_pixel(win.size, sc.half_size, depth, ppm1), tap_offset_of(config_));
        if (config_.fit_quads_from_vertices && next.fitted) {
          // The quad and the cleared rect from the skinned vertices, widened by the taps' reach as
          // the coverage pass widens its rectangle (snapshot_gpu): no pass, the same pictures.
          const ModelFrame mf = model_frame(sc, ch);
          SkinnedExtent se(sc, mf, pal, np, bc.first_row + f0, bc.first_row + f1, blend);
          for (const Vertex& v : m.lods[slod].vertices) se.add(v);
          next.fitted = !se.fit(win.size, reach, next.rect, snap_rect);
        }
        cs = next;
        out.snapshots.add(slod,
            snapshot_gpu(inst, sc, radius, win, page, snap_rect, next.rect, slot, next.fitted, reach));
        ++st.snapshots;
        st.snapshot_triangles += m.lods[slod].triangle_count();
        ++*out.budget_used;
      }
      // The old snapshot is drawn where the character stands now (Ta moves with it).
      out.billboards->push_back(billboard(ta, cs, ch.scale / cs.scale, page, slot, cam_right, cam_up));
      st.quad_texels += rect_texels(cs.rect, win.size);
      ++st.impostors;
      ++st.impostors_per_window[win.size_class];
    }
  }
  if (as_geometry) draw_geometry();
}

void FramePlanner::follow_ids(const Crowd& crowd) {
  const std::size_t n = crowd.size(), old = cache_.size(), common = std::min(n, old);
  std::size_t same = 0;
  while (same < common && cache_[same].owner == crowd[same].id) ++same;
  if (same == common) {  // unchanged, or characters added or removed at the end (begin_frame's resizes)
    if (n > old) {
      cache_.resize(n);
      for (std::size_t i = old; i < n; ++i) cache_[i].owner = crowd[i].id;
    }
    return;
  }
  const std::size_t parts = parts_ > 1 ? static_cast<std::size_t>(parts_) : 0;
  const bool with_parts = parts > 0 && part_cache_.size() == old * parts;
  // Each character's old slot (kNone: a new one), worked out in the scratch lists (kept, so that a
  // game's changes allocate nothing once they have been this large). First the characters still at
  // their index (a character without an id keeps its index's slot if that had none), so that of
  // two with one id the one that stayed keeps its own; then the others by id.
  constexpr std::uint32_t kNone = 0xffffffffu;
  std::vector<std::uint32_t>& from = follow_.from;
  std::vector<std::uint8_t>& taken = follow_.taken;
  from.assign(n, kNone);
  taken.assign(old, 0);
  for (std::size_t i = 0; i < common; ++i)
    if (cache_[i].owner == crowd[i].id) {
      from[i] = static_cast<std::uint32_t>(i);
      taken[i] = 1;
    }
  // The other slots by owner in an open-addressed table (linear probing, a power of two at least
  // twice their number): linear in the crowd where sorting them took 0.4 ms at 10,000 (a crowd
  // reordered every frame, bench_runtime's BM_UpdateReordered).
  std::size_t others = 0;
  for (std::size_t i = 0; i < old; ++i) others += !taken[i] && cache_[i].owner != 0;
  if (others > 0) {
    int bits = 4;
    while ((std::size_t{1} << bits) < 2 * others) ++bits;
    const std::size_t mask = (std::size_t{1} << bits) - 1;
    auto home = [&](std::uint32_t id) { return static_cast<std::size_t>((id * 0x9E3779B1u) >> (32 - bits)); };
    auto& table = follow_.table;  // (owner, slot); owner 0: empty
    table.assign(mask + 1, {0u, 0u});
    for (std::size_t i = 0; i < old; ++i) {
      if (taken[i] || cache_[i].owner == 0) continue;
      std::size_t h = home(cache_[i].owner);
      while (table[h].first != 0) h = (h + 1) & mask;
      table[h] = {cache_[i].owner, static_cast<std::uint32_t>(i)};
    }
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t id = crowd[i].id;
      if (from[i] != kNone || id == 0) continue;
      for (std::size_t h = home(id); table[h].first != 0; h = (h + 1) & mask)
        if (table[h].first == id && !taken[table[h].second]) {  // a copy with one id: the next slot
          from[i] = table[h].second;
          taken[from[i]] = 1;
          break;
        }
    }
  }
  std::vector<CacheState>& next = follow_.cache;
  std::vector<PartCache>& next_parts = follow_.parts;
  next.resize(n);
  next_parts.resize(with_parts ? n * parts : 0);
  for (std::size_t i = 0; i < n; ++i) {
    const bool kept = from[i] != kNone;
    next[i] = kept ? cache_[from[i]] : CacheState{};
    next[i].owner = crowd[i].id;
    if (!with_parts) continue;
    const auto to = next_parts.begin() + static_cast<std::ptrdiff_t>(i * parts);
    if (kept)
      std::copy_n(part_cache_.begin() + static_cast<std::ptrdiff_t>(from[i] * parts), parts, to);
    else
      std::fill_n(to, parts, PartCache{});
  }
  for (std::size_t i = 0; i < old; ++i) {
    if (taken[i]) continue;
    if (cache_[i].window.valid()) atlas_.release(cache_[i].window);
    if (with_parts)
      for (std::size_t k = i * parts; k < (i + 1) * parts; ++k)
        if (part_cache_[k].window.valid()) atlas_.release(part_cache_[k].window);
  }
  cache_.swap(next);
  if (with_parts) part_cache_.swap(next_parts);
}

std::size_t FramePlanner::begin_frame(const Crowd& crowd, const SceneCamera& camera, float time, RenderMode mode) {
  const Model& m = *model_;
  const std::size_t n = crowd.size();
  Frame& fr = frame_;
  fr.crowd = &crowd;
  // The last plan was drawn by a renderer that holds none of this cache's snapshots (a renderer
  // made anew without invalidate()): its impostors were drawn from empty windows; all are taken anew.
  if (plan_.drawn_from_another_atlas) {
    plan_.drawn_from_another_atlas = false;
    invalidate();
  }
  // Part cards on or off: start over with the other kind of windows.
  const int want_parts = config_.part_cards ? static_cast<int>(m.body_parts().size()) : 1;
  if (want_parts != parts_) {
    for (auto& c : cache_) {
      if (c.window.valid()) atlas_.release(c.window);
      const std::uint32_t owner = c.owner;
      c = CacheState{};
      c.owner = owner;
    }
    for (auto& pc : part_cache_)
      if (pc.window.valid()) atlas_.release(pc.window);
    part_cache_.clear();
    parts_ = want_parts;
  }
  follow_ids(crowd);
  if (parts_ > 1 && part_cache_.size() != n * parts_) {
    for (std::size_t k = n * parts_; k < part_cache_.size(); ++k)
      if (part_cache_[k].window.valid()) atlas_.release(part_cache_[k].window);
    part_cache_.resize(n * parts_);
  }
  if (cache_.size() > n) {  // characters removed at the end (follow_ids grew it): give their windows back
    for (std::size_t i = n; i < cache_.size(); ++i)
      if (cache_[i].window.valid()) atlas_.release(cache_[i].window);
    cache_.resize(n);
  }
  for (auto& g : plan_.geometry) g.clear();
  for (auto& s : plan_.snapshots) s.clear();
  plan_.billboards.clear();
  if (plan_.billboards.capacity() < n * parts_) plan_.billboards.reserve(n * parts_);
  plan_.camera = camera;
  fr.st = FrameStats{};
  fr.st.characters = static_cast<int>(n);
  fr.budget_used = 0;

  // Frustum planes (world) from the view-projection matrix, for the snapshot sphere.
  const glm::mat4 vp = camera.projection() * camera.view();
  FrameSetup& fs = fr.setup;
  std::array<glm::vec4, 6>& planes = fs.planes;
  for (int i = 0; i < 3; ++i) {
    planes[2 * i] = glm::vec4(vp[0][3] + vp[0][i], vp[1][3] + vp[1][i], vp[2][3] + vp[2][i], vp[3][3] + vp[3][i]);
    planes[2 * i + 1] = glm::vec4(vp[0][3] - vp[0][i], vp[1][3] - vp[1][i], vp[2][3] - vp[2][i], vp[3][3] - vp[3][i]);
  }
  for (auto& p : planes) p /= glm::length(glm::vec3(p));
  camera_axes(camera, fs.cam_right, fs.cam_up, fs.fwd);
  fs.camera = camera;
  fs.time = time;
  fs.mode = mode;
  fs.ppm1 = camera.pixels_per_metre(1.0f);
  fs.impostor_mode = mode != RenderMode::kGeometry;
  if (fs.impostor_mode) ++fs.frame;
  const CacheConfig& cc = config_.cache;
  fs.cos_view = std::cos(glm::radians(cc.view_threshold_deg));
  fs.cos_ahead = std::cos(std::min(glm::radians(cc.view_threshold_deg), 3.14159265f) * cc.ahead_fraction);
  fs.switch_px = static_cast<float>(config_.windows.size[0]) * config_.geometry_switch;
  fs.page = static_cast<float>(atlas_.page_size());
  // LOD of each window class (section 4.3: the snapshot uses the level that matches the window).
  fs.window_lod = {};
  for (int w = 0; w < config_.windows.count; ++w) fs.window_lod[w] = lod_for(static_cast<float>(config_.windows.size[w]), camera.height);

  fs.budget = cc.refresh_budget > 0 && parts_ == 1;
  fs.ahead = cc.ahead_fraction > 0.0f && cc.ahead_fraction < 1.0f && cc.ahead_count > 0 && parts_ == 1;
  budget_left_ = cc.refresh_budget;
  pending_.clear();
  ahead_.clear();
  pending_parts_.clear();
  part_jobs_.clear();
  starved_.clear();
  if (starved_.capacity() < n) starved_.reserve(n);
  if (parts_ > 1) refreshed_.assign(n, 0);

  // Crowds of kParallelCharacters work and more (without part cards) are planned in chunks, each
  // into its own lists, joined in crowd order by end_frame; characters whose atlas window must be
  // allocated or changed are then planned one by one in crowd order (the allocator is shared,
  // and its choices must not depend on the threads), after the others. So the plan is the same
  // whatever the number of threads: the work depends on the crowd and the frames before only.
  fr.chunks = 0;
  fr.joined = false;
  fr.threads = 1;
  // Part cards: a character is a unit of work per card (each card is tested every frame).
  fr.work = n * static_cast<std::size_t>(parts_) + kRefreshWork * static_cast<std::size_t>(fs.impostor_mode ? last_snapshots_ : 0);
  if (fr.work >= kParallelCharacters) chunk_frame();
  return fr.chunks;
}

std::size_t FramePlanner::chunk_frame() {
  Frame& fr = frame_;
  const std::size_t n = fr.crowd->size();
  if (n == 0 || fr.chunks > 0) return fr.chunks;
  // As many chunks whatever the work (its lists then stop growing once warm): four a thread of
  // the pool, at least kCharactersPerChunk characters each.
  fr.chunks = std::clamp<std::size_t>(n / kCharactersPerChunk, 1, 4 * std::size_t{planner_threads()});
  if (chunks_.size() < fr.chunks) chunks_.resize(fr.chunks);
  return fr.chunks;
}

unsigned FramePlanner::max_useful_threads(std::size_t work) {
  // As many threads as the crowd keeps busy (kCharactersPerThread).
  return static_cast<unsigned>(std::clamp<std::size_t>(work / kCharactersPerThread, 1, planner_threads()));
}

void FramePlanner::plan_chunk(std::size_t c) {
  const Frame& fr = frame_;
  const Crowd& crowd = *fr.crowd;
  const std::size_t n = crowd.size();
  const FrameSetup& fs = fr.setup;
  Chunk& k = chunks_[c];
  const std::size_t first = n * c / fr.chunks, end = n * (c + 1) / fr.chunks;
  k.clear(model_->lods.size(), end - first, (end - first) * static_cast<std::size_t>(parts_));
  const Out o{&k.geometry,    k.sink(),    &k.billboards, &k.pending,       &k.st,
              &k.budget_used, &k.deferred, false,          fs.ahead ? &k.ahead : nullptr, false,
              &k.pending_parts, &k.part_jobs};
  for (std::size_t i = first; i < end; ++i) plan_character(i, crowd[i], fs, o);
}

const FramePlan& FramePlanner::plan(const Crowd& crowd, const SceneCamera& camera, float time, RenderMode mode) {
  const std::size_t chunks = begin_frame(crowd, camera, time, mode);
  const unsigned used = chunks > 0 ? max_useful_threads(frame_.work) : 1;
  frame_.threads = used;
  auto run_chunk = [this](std::size_t c) { plan_chunk(c); };
  if (used > 1) {
    pool_->run(chunks, run_chunk, used);
  } else {
    for (std::size_t c = 0; c < chunks; ++c) run_chunk(c);
  }
  return end_frame();
}

void FramePlanner::plan_many(std::span<FramePlanner* const> planners, std::span<const Crowd* const> crowds,
                             const SceneCamera& camera, float time, RenderMode mode) {
  assert(planners.size() == crowds.size());
  // Every planner's chunks in one call on the first planner's pool: one wake-up for all. Crowds
  // too small for threads alone are chunked too where the joint work is enough for them (the
  // flow test bed's four bodies at 1,000 humans: 250 characters a model, each planned on one
  // thread before). Such a plan holds what plan() makes, in a chunked crowd's order.
  std::size_t total = 0, work = 0;
  std::array<std::size_t, 65> first{};  // planners' first chunk in the joint numbering
  const std::size_t joint = std::min<std::size_t>(planners.size(), 64);
  std::array<std::size_t, 64> chunks{};
  std::size_t joint_work = 0;
  for (std::size_t p = 0; p < joint; ++p) {
    chunks[p] = planners[p]->begin_frame(*crowds[p], camera, time, mode);
    joint_work += planners[p]->frame_.work;
  }
  if (joint_work >= kParallelCharacters)
    for (std::size_t p = 0; p < joint; ++p) chunks[p] = planners[p]->chunk_frame();
  for (std::size_t p = 0; p < planners.size(); ++p) {
    const std::size_t c = p < joint ? chunks[p] : planners[p]->begin_frame(*crowds[p], camera, time, mode);
    if (p < joint) {
      first[p] = total;
      total += c;
      if (c > 0) work += planners[p]->frame_.work;
    } else {  // past 64 planners: on their own (a crowd of that many models plans them in turn)
      for (std::size_t k = 0; k < c; ++k) planners[p]->plan_chunk(k);
    }
  }
  first[joint] = total;
  if (total > 0) {
    auto run_chunk = [&](std::size_t g) {
      const std::size_t p = static_cast<std::size_t>(std::upper_bound(first.begin(), first.begin() + joint + 1, g) - first.begin()) - 1;
      planners[p]->plan_chunk(g - first[p]);
    };
    FramePlanner& lead = *planners[0];
    const unsigned used = lead.max_useful_threads(work);
    for (std::size_t p = 0; p < joint; ++p) planners[p]->frame_.threads = first[p + 1] > first[p] ? used : 1;
    if (used > 1) {
      lead.pool_->run(total, run_chunk, used);
    } else {
      for (std::size_t g = 0; g < total; ++g) run_chunk(g);
    }
  }
  // Each planner's chunks joined on the threads (they touch their own planner's lists; where one
  // thread would do, end_frame joins them), then the serial rest, planner by planner (the atlas
  // may be shared). At 10,000 humans of four models the joins took 0.17-0.18 ms a frame one after
  // the other on the 2-core machine (docs/results.md, fifty-fourth session).
  const unsigned join_threads =
      total > 0 ? std::min<unsigned>(planners[0]->max_useful_threads(work), static_cast<unsigned>(joint)) : 1;
  auto join = [&](std::size_t p) { planners[p]->join_chunks(); };
  if (join_threads > 1) planners[0]->pool_->run(joint, join, join_threads);
  for (FramePlanner* p : planners) p->end_frame();
}

void FramePlanner::join_chunks() {
  Frame& fr = frame_;
  if (fr.joined) return;
  fr.joined = true;
  if (fr.chunks == 0) return;
  FrameStats& st = fr.st;
  int& budget_used = fr.budget_used;
  const std::size_t chunks = fr.chunks;
  for (std::size_t c = 0; c < chunks; ++c) {
    Chunk& k = chunks_[c];
    const auto base = static_cast<std::uint32_t>(plan_.billboards.size());
    for (std::size_t l = 0; l < plan_.geometry.size(); ++l)
      plan_.geometry[l].insert(plan_.geometry[l].end(), k.geometry[l].begin(), k.geometry[l].end());
    k.join_snapshots(plan_.snapshots);
    plan_.billboards.insert(plan_.billboards.end(), k.billboards.begin(), k.billboards.end());
    for (PendingRefresh& r : k.pending) {
      r.billboard += base;
      pending_.push_back(r);
    }
    for (PendingRefresh& r : k.ahead) {
      r.billboard += base;
      ahead_.push_back(r);
    }
    const auto job_base = static_cast<std::uint32_t>(part_jobs_.size());
    for (PendingPart& r : k.pending_parts) {
      r.billboard += base;
      r.job += job_base;
      pending_parts_.push_back(r);
    }
    part_jobs_.insert(part_jobs_.end(), k.part_jobs.begin(), k.part_jobs.end());
    add_stats(st, k.st);
    budget_used += k.budget_used;
  }
}

const FramePlan& FramePlanner::end_frame() {
  Frame& fr = frame_;
  const Crowd& crowd = *fr.crowd;
  const std::size_t n = crowd.size();
  const FrameSetup& fs = fr.setup;
  FrameStats& st = fr.st;
  int& budget_used = fr.budget_used;
  const Out serial{&plan_.geometry,           SnapshotSink{&plan_.snapshots}, &plan_.billboards, &pending_, &st,
                   &budget_used,              nullptr,                         false,
                   fs.ahead ? &ahead_ : nullptr, false,                         &pending_parts_,   &part_jobs_,
                   &starved_};
  if (fr.chunks > 0) {
    join_chunks();
    for (std::size_t c = 0; c < fr.chunks; ++c)
      for (std::uint32_t i : chunks_[c].deferred) plan_character(i, crowd[i], fs, serial);
  } else {
    for (std::size_t i = 0; i < n; ++i) plan_character(i, crowd[i], fs, serial);
  }
  // Characters the full atlas gave no window, now that every other has been planned: windows of
  // characters not drawn this frame may be taken back for them (reclaim), in crowd order.
  if (!starved_.empty()) {
    Out retry = serial;
    retry.starved = nullptr;
    retry.reclaim = true;
    for (std::uint32_t i : starved_) plan_character(i, crowd[i], fs, retry);
  }
  budget_left_ -= budget_used;
  // The budget left goes to the stalest; the others wait (section 7, item 1). The chosen ones are
  // planned again, forced: the same tests, now refreshed (their snapshot, cache state and quad).
  if (!pending_.empty()) {
    const std::size_t take = stalest_first(pending_, budget_left_);
    refresh_listed(pending_, take, false);
    st.deferred_refreshes = static_cast<int>(pending_.size() - take);
    budget_left_ -= static_cast<int>(take);
  }
  // Refreshes ahead: only in a frame that takes snapshots anyway, within the budget's rest.
  if (!ahead_.empty() && st.snapshots > 0) {
    const int room = fs.budget ? std::min(budget_left_, config_.cache.ahead_count) : config_.cache.ahead_count;
    const std::size_t take = stalest_first(ahead_, room);
    refresh_listed(ahead_, take, true);
    st.ahead_refreshes = static_cast<int>(take);
    budget_left_ -= static_cast<int>(take);
  }
  if (!pending_parts_.empty()) {
    const std::size_t take = stalest_first(pending_parts_, budget_left_);
    for (std::size_t k = 0; k < take; ++k) {
      const PendingPart& r = pending_parts_[k];
      const PartJob& job = part_jobs_[r.job];
      PartCache& pc = part_cache_[r.order];
      SnapshotGpu snap;
      std::size_t tris = 0;
      const PartCache next = part_card(job, crowd[job.character], snap, tris);
      st.quad_texels += rect_texels(next.rect, next.window.size) - rect_texels(pc.rect, pc.window.size);
      pc = next;
      plan_.billboards[r.billboard] = part_billboard(next, job.bone, glm::mat3(1.0f));
      plan_.snapshots[static_cast<std::size_t>(job.slod)].push_back(snap);
      ++st.part_snapshots;
      st.snapshot_triangles += tris;
      const std::size_t character = r.order / static_cast<std::size_t>(parts_);
      if (!refreshed_[character]) {
        refreshed_[character] = 1;
        ++st.snapshots;
      }
    }
    st.deferred_refreshes = static_cast<int>(pending_parts_.size() - take);
  }
  st.refresh_fraction = st.impostors > 0 ? static_cast<float>(st.snapshots) / static_cast<float>(st.impostors) : 0.0f;
  if (st.part_cards > 0) st.refresh_fraction = static_cast<float>(st.part_snapshots) / static_cast<float>(st.part_cards);
  st.atlas_pages = atlas_.max_pages();
  st.atlas_pages_used = atlas_.pages_used();
  st.atlas_windows_used = atlas_.windows_used();
  st.atlas_pixel_use = atlas_.pixel_use();
  st.planner_threads = static_cast<int>(fr.chunks > 0 ? fr.threads : 1);
  plan_.stats = st;
  plan_.cache_id = cache_id_;
  plan_.cache_plans_before = cache_plans_;
  for (const auto& s : plan_.snapshots)
    if (!s.empty()) {
      ++cache_plans_;
      break;
    }
  if (fs.impostor_mode) last_snapshots_ = st.snapshots;
  return plan_;
}

// Plans the first `take` impostors of `list` again, forced (`ahead`: refreshed although their
// tests passed), in chunks on the threads like the crowd, and swaps their billboards and snapshots
// into the plan in the list's order.
void FramePlanner::refresh_listed(const std::vector<PendingRefresh>& list, std::size_t take, bool ahead) {
  if (take == 0) return;
  const Crowd& crowd = *frame_.crowd;
  const FrameSetup& fs = frame_.setup;
  FrameStats& st = frame_.st;
  for (std::size_t k = 0; k < take; ++k) {
    const CacheState& before = cache_[list[k].order];
    st.quad_texels -= rect_texels(before.rect, before.window.size);
  }
  const unsigned used = static_cast<unsigned>(std::clamp<std::size_t>(take / kForcedPerThread, 1, planner_threads()));
  const std::size_t chunks = std::min<std::size_t>(take, 4 * std::size_t{used});
  if (chunks_.size() < chunks) chunks_.resize(chunks);
  auto run_chunk = [&](std::size_t c) {
    Chunk& k = chunks_[c];
    const std::size_t refreshes = take * (c + 1) / chunks - take * c / chunks;
    k.clear(model_->lods.size(), refreshes, refreshes);
    const Out o{&k.geometry, k.sink(), &k.billboards, nullptr, &k.st, &k.budget_used, nullptr, true, nullptr, ahead};
    for (std::size_t j = take * c / chunks, e = take * (c + 1) / chunks; j < e; ++j)
      plan_character(list[j].order, crowd[list[j].order], fs, o);
  };
  if (used > 1) {
    pool_->run(chunks, run_chunk, used);
  } else {
    for (std::size_t c = 0; c < chunks; ++c) run_chunk(c);
  }
  for (std::size_t c = 0; c < chunks; ++c) {
    const Chunk& k = chunks_[c];
    const std::size_t first = take * c / chunks;
    assert(k.billboards.size() == take * (c + 1) / chunks - first && k.st.snapshots == static_cast<int>(k.billboards.size()));
    for (std::size_t j = 0; j < k.billboards.size(); ++j) plan_.billboards[list[first + j].billboard] = k.billboards[j];
    k.join_snapshots(plan_.snapshots);
    st.quad_texels += k.st.quad_texels;
    st.snapshots += k.st.snapshots;
    st.lead_snapshots += k.st.lead_snapshots;
    st.snapshot_triangles += k.st.snapshot_triangles;
  }
}

std::optional<AtlasWindow> FramePlanner::allocate_or_reclaim(int size_class, bool may_reclaim) {
  std::optional<AtlasWindow> w = atlas_.allocate(size_class);
  while (!w && may_reclaim && reclaim(size_class)) w = atlas_.allocate(size_class);
  return w;
}

void FramePlanner::release_character_windows(std::size_t i) {
  CacheState& cs = cache_[i];
  auto give_back = [&](AtlasWindow& w) {
    if (!w.valid()) return;
    --reclaim_.page_windows[static_cast<std::size_t>(w.page - atlas_.first_page())];
    atlas_.release(w);
    w = AtlasWindow{};
  };
  give_back(cs.window);
  if (parts_ > 1 && part_cache_.size() == cache_.size() * static_cast<std::size_t>(parts_))
    for (std::size_t k = i * parts_; k < (i + 1) * parts_; ++k) give_back(part_cache_[k].window);
  cs.valid = false;  // a snapshot anew, in a new window, when it is drawn again
  ++frame_.st.atlas_reclaimed;
}

bool FramePlanner::reclaim(int size_class) {
  Reclaim& r = reclaim_;
  const std::uint32_t frame = frame_.setup.frame;
  const std::size_t parts = parts_ > 1 && part_cache_.size() == cache_.size() * static_cast<std::size_t>(parts_)
                                ? static_cast<std::size_t>(parts_)
                                : 0;
  auto holds = [&](std::size_t i, auto&& each) {  // calls each(window) for character i's windows
    if (cache_[i].window.valid()) each(cache_[i].window);
    for (std::size_t k = i * parts; k < (i + 1) * parts; ++k)
      if (part_cache_[k].window.valid()) each(part_cache_[k].window);
  };
  // A candidate still: not drawn this frame, and holding windows (not taken back since).
  auto candidate = [&](std::size_t i) {
    bool any = false;
    holds(i, [&](const AtlasWindow&) { any = true; });
    return any && cache_[i].drawn != frame;
  };
  if (r.frame != frame) {
    // The characters not drawn this frame that hold windows, the longest undrawn first: grouped by
    // the bit length of the impostor frames since they were drawn (a counting sort, no comparison
    // of slots), in crowd order within a group.
    r.frame = frame;
    r.found.clear();
    r.order.clear();
    if (r.found.capacity() < cache_.size()) {  // room for every slot: no allocation in a later frame
      r.found.reserve(cache_.size());
      r.order.reserve(cache_.size());
    }
    r.next.fill(0);
    r.page_windows.assign(static_cast<std::size_t>(atlas_.max_pages()), 0);
    std::array<std::uint32_t, 34> start{};
    auto group = [&](std::uint32_t i) { return 32 - std::bit_width(frame - cache_[i].drawn); };  // oldest: 0
    for (std::size_t i = 0; i < cache_.size(); ++i) {
      if (!candidate(i)) continue;
      r.found.push_back(static_cast<std::uint32_t>(i));
      ++start[static_cast<std::size_t>(group(static_cast<std::uint32_t>(i))) + 1];
      holds(i, [&](const AtlasWindow& w) { ++r.page_windows[static_cast<std::size_t>(w.page - atlas_.first_page())]; });
    }
    for (std::size_t g = 1; g < start.size(); ++g) start[g] += start[g - 1];
    r.order.resize(r.found.size());
    for (std::uint32_t i : r.found) r.order[start[static_cast<std::size_t>(group(i))]++] = i;
  }
  // The longest undrawn holding a window of this class.
  for (std::size_t& k = r.next[static_cast<std::size_t>(size_class)]; k < r.order.size(); ++k) {
    const std::uint32_t i = r.order[k];
    if (!candidate(i)) continue;
    bool of_class = false;
    holds(i, [&](const AtlasWindow& w) { of_class |= w.size_class == size_class; });
    if (!of_class) continue;
    release_character_windows(i);
    ++k;
    return true;
  }
  // Else a page of another class whose windows only such characters hold: all of them.
  for (int p = 0; p < atlas_.max_pages(); ++p) {
    const int page = atlas_.first_page() + p;
    const int held = r.page_windows[static_cast<std::size_t>(p)];
    if (held == 0 || atlas_.page_class(page) < 0 || held != atlas_.page_windows(page)) continue;
    for (std::uint32_t i : r.order) {
      if (!candidate(i)) continue;
      bool on_page = false;
      holds(i, [&](const AtlasWindow& w) { on_page |= w.page == page; });
      if (on_page) release_character_windows(i);
    }
    return true;
  }
  return false;
}

// The coverage pass reads each fitted snapshot's texels once (ImpostorConfig::
// fit_quads_to_coverage), and the smaller quad pays that back only over the frames the snapshot is
// drawn. A snapshot that replaces one drawn for fewer than kFitAfterFrames frames is likely to be
// as short-lived (both thresholds 0, a fast-turning camera, a part swinging past its threshold),
// so its quad stays the planner's box.
bool FramePlanner::fit_quad(std::uint32_t last, std::uint32_t frame) const {
  return config_.fit_quads_to_coverage && (last == 0 || frame - last >= kFitAfterFrames);
}

// The direction card job.part's snapshot is taken along (palette space): the mean of the part's
// line of sight over the coming frames (the clip played on, the eye carried on at its velocity in
// the character's frame) until it has turned by the view threshold from where it is now, the time
// a card taken now would last.
glm::vec3 FramePlanner::lead_direction(const PartJob& job, const Character& ch, float time) const {
  const Model& m = *model_;
  const BodyPart& bp = m.body_parts()[static_cast<std::size_t>(job.part)];
  const BakedClip& bc = m.baked_clips()[static_cast<std::size_t>(job.clip)];
  const auto pal = m.baked_palette();
  const int np = static_cast<int>(m.palette.size());
  const glm::vec3 c = bp.centre;
  glm::vec3 los0(0.0f), sum(0.0f);
  for (int k = 0; k <= kLeadSteps; ++k) {
    const float dt = static_cast<float>(k) * kLeadStep;
    const BakedFrames g = baked_frames(m, ch, time + dt);
    const glm::mat4 pm = palette_matrix(pal, np, bc, g.f0, g.f1, g.blend, bp.bone);
    const glm::vec3 e = job.eye_char + job.eye_vel * dt;
    const glm::vec3 los = glm::normalize(glm::inverse(glm::mat3(pm)) * (glm::vec3(pm * glm::vec4(c, 1.0f)) - e));
    if (k == 0) los0 = los;
    else if (glm::dot(los, los0) < job.cos_view) break;
    sum += los;
  }
  return glm::normalize(sum);
}

FramePlanner::PartCache FramePlanner::part_card(const PartJob& job, const Character& ch, SnapshotGpu& s,
                                                std::size_t& tris) const {
  const Model& m = *model_;
  const FrameSetup& fs = frame_.setup;
  const SceneCamera& camera = fs.camera;
  const int p = job.part;
  const BodyPart& bp = m.body_parts()[static_cast<std::size_t>(p)];
  const PartCache& pc = part_cache_[job.character * static_cast<std::size_t>(parts_) + static_cast<std::size_t>(p)];
  const AtlasWindow& win = pc.window;
  const int slot = coverage_slot_of(win);
  const float ppm1 = fs.ppm1;
  const float page = fs.page;
  const glm::mat4& bone = job.bone;
  const glm::vec3& centre = job.centre;
  const float r = bp.radius * ch.scale;
  // A leading card's snapshot eye: as far from the part as the camera, on the mean line of sight
  // ahead.
  const glm::vec3 eye = job.lead ? centre - glm::length(centre - camera.eye) *
                                                glm::normalize(glm::mat3(bone) * lead_direction(job, ch, fs.time))
                                 : camera.eye;
  SnapshotCamera cam = make_snapshot_camera(centre, eye, camera.up, r,
                                            config_.snapshot_distance > 0 ? config_.snapshot_distance * ch.scale : 0.0f,
                                            config_.perspective_snapshots);
  if (config_.texel_per_pixel && cam.perspective)
    cam.half_size = std::max(cam.half_size, half_size_at(win.size, config_.texels_per_pixel, cam.distance, ppm1));
  // The snapshot's direction, and the line of sight to the part now, which the view test also
  // follows (the same without a lead).
  const glm::vec3 vo = cam.vo;
  const glm::vec3 los = job.lead ? glm::normalize(centre - camera.eye) : cam.vo;
  if (config_.aligned_snapshots)
    if (auto a = make_aligned_snapshot_camera(camera, centre, r, win.size, config_.texels_per_pixel, config_.aligned_phase)) cam = *a;
  // The card at snapshot time (the window's plane through its centre), in the bone's palette space.
  PartCache next = pc;
  const glm::mat4 inv = glm::inverse(bone);
  next.centre = glm::vec3(inv * glm::vec4(cam.ta, 1.0f));
  next.axis_x = glm::vec3(inv * glm::vec4(cam.ho * cam.half_size, 0.0f));
  next.axis_y = glm::vec3(inv * glm::vec4(cam.uo * cam.half_size, 0.0f));
  next.normal = glm::vec3(inv * glm::vec4(los, 0.0f));
  next.card_normal = glm::vec3(inv * glm::vec4(vo, 0.0f));
  next.half_size = cam.half_size;
  // The snapshot's eye in the card's frame (units of the half size): carried with the axes.
  next.snap = config_.parallax_cards && cam.perspective && config_.snapshot_samples <= 1
                  ? glm::vec4(cam.offset / cam.half_size, cam.distance / cam.half_size, r / cam.half_size)
                  : glm::vec4(0.0f);
  next.posture = job.posture;
  next.fitted = fit_quad(pc.taken, fs.frame);
  next.taken = fs.frame;
  next.rect = glm::vec4(-1, -1, 1, 1);
  glm::vec4 snap_rect = next.rect;
  if (config_.tight_quads) {
    // The part's box (palette space, over all frames).
    PlaneExtent e;
    add_placed_box(cam, bone, bp.box_min, bp.box_max, cam.ta, e);
    const WindowRects rr = window_rects(e, win.size);
    next.rect = rr.quad;
    snap_rect = rr.snapshot;
  }
  const float reach = taps_reach(window_texels_per_pixel(win.size, cam.half_size, job.depth, ppm1), tap_offset_of(config_));
  const PartIndices& pi = m.part_indices(job.slod);
  if (config_.fit_quads_from_vertices && next.fitted) {
    // As for whole impostors (plan_character): the part's triangles' vertices (each primitive's
    // range of the part index list) instead of the coverage pass.
    const MeshLod& ml = m.lods[static_cast<std::size_t>(job.slod)];
    const ModelFrame mf = model_frame(cam, ch);
    SkinnedExtent se(cam, mf, m.baked_palette(), static_cast<int>(m.palette.size()), static_cast<int>(job.inst.anim.y),
                     static_cast<int>(job.inst.anim.z), job.inst.anim.w);
    for (std::size_t k = 0; k < ml.primitives.size(); ++k) {
      const PartIndices::Range& range = pi.ranges[k * static_cast<std::size_t>(parts_) + static_cast<std::size_t>(p)];
      se.add_once(ml, std::span<const std::uint32_t>(pi.indices).subspan(range.first, range.count));
    }
    next.fitted = !se.fit(win.size, reach, next.rect, snap_rect);
  }
  s = snapshot_gpu(job.inst, cam, r, win, page, snap_rect, next.rect, slot, next.fitted, reach);
  s.part.x = static_cast<float>(p);
  const std::size_t prims = m.lods[static_cast<std::size_t>(job.slod)].primitives.size();
  tris = 0;
  for (std::size_t k = 0; k < prims; ++k) {
    const PartIndices::Range& range = pi.ranges[k * static_cast<std::size_t>(parts_) + static_cast<std::size_t>(p)];
    tris += (range.count + range.caps) / 3;  // its caps drawn too
  }
  return next;
}

BillboardGpu FramePlanner::part_billboard(const PartCache& c, const glm::mat4& bone, const glm::mat3& t) const {
  const AtlasWindow& win = c.window;
  const float page = static_cast<float>(atlas_.page_size());
  return BillboardGpu{glm::vec4(glm::vec3(bone * glm::vec4(c.centre, 1.0f)), c.half_size),
                      glm::vec4(win.x / page, win.y / page, (win.x + win.size) / page, (win.y + win.size) / page),
                      glm::vec4(static_cast<float>(win.page), static_cast<float>(coverage_slot_of(win)), c.fitted ? 1.0f : 0.0f, 0.0f),
                      c.rect,
                      glm::vec4(t * glm::vec3(bone * glm::vec4(c.axis_x, 0.0f)), 1.0f),
                      glm::vec4(t * glm::vec3(bone * glm::vec4(c.axis_y, 0.0f)), 1.0f),
                      c.snap};
}

FramePlanner::PartsPlanned FramePlanner::plan_parts(std::size_t i, const Character& ch, const BakedClip& bc, int f0,
                                                    int f1, float blend, const InstanceGpu& inst, const glm::vec3& ta,
                                                    float radius, float pixels, const SceneCamera& camera, float time,
                                                    const Out& out) {
  (void)radius;
  FrameStats& st = *out.st;
  const Model& m = *model_;
  const auto parts = m.body_parts();
  const int np = static_cast<int>(m.palette.size());
  const int count = std::min(parts_, kMaxBodyParts);
  CacheState& cs = cache_[i];
  PartCache* pcs = &part_cache_[i * parts_];
  const glm::vec3 fwd = glm::normalize(camera.target - camera.eye);
  const float ppm1 = camera.pixels_per_metre(1.0f);
  const auto pal = m.baked_palette();
  // Character placement x the part's bone matrix now (model space -> world).
  const float sc = ch.scale;
  const glm::mat4 place = placement(ch);
  std::array<glm::mat4, kMaxBodyParts> bone;
  std::array<glm::vec3, kMaxBodyParts> centre;
  std::array<float, kMaxBodyParts> depth;  // of the centre along the view direction
  std::array<bool, kMaxBodyParts> due;
  // Limb cards that turn about their axis (ImpostorConfig::turn_limb_cards), and by how much.
  std::array<bool, kMaxBodyParts> turns;
  std::array<glm::mat3, kMaxBodyParts> turn;
  for (int p = 0; p < count; ++p) {
    turns[p] = config_.turn_limb_cards && parts[p].elongation >= kLimbElongation && parts[p].flatness <= kLimbFlatness;
    turn[p] = glm::mat3(1.0f);
  }
  std::array<int, kMaxBodyParts> wclass;
  bool allocates = false;  // a card's window must be allocated or change size class
  for (int p = 0; p < count; ++p) {
    bone[p] = place * palette_matrix(pal, np, bc, f0, f1, blend, parts[p].bone);
    centre[p] = glm::vec3(bone[p] * glm::vec4(parts[p].centre, 1.0f));
    depth[p] = glm::dot(centre[p] - camera.eye, fwd);
    float px = 2.0f * parts[p].radius * sc * ppm1 / std::max(depth[p], 1e-3f);
    if (config_.aligned_snapshots) {
      const float a = aligned_pixels(camera, centre[p], parts[p].radius * sc);
      if (std::isfinite(a)) px = a;
    }
    wclass[p] = choose_window(config_.windows, std::max(px * config_.texels_per_pixel,
                                                        static_cast<float>(config_.smallest_part_window)));
    allocates |= !pcs[p].window.valid() || pcs[p].window.size_class != wclass[p];
  }
  if (allocates && out.deferred) {  // the atlas is served in crowd order, after the parallel pass
    out.deferred->push_back(static_cast<std::uint32_t>(i));
    return PartsPlanned::kDeferred;
  }
  const bool all = !cs.valid;
  bool window_change = false;
  // Its windows are in use this frame: reclaim, which a card's allocation may call, takes none of
  // them (nor of the cards served before it in this loop).
  cs.drawn = frame_.setup.frame;
  for (int p = 0; p < count; ++p) {
    PartCache& pc = pcs[p];
    const int wclass_p = wclass[p];
    due[p] = all;
    if (pc.window.valid() && pc.window.size_class != wclass_p) {
      atlas_.release(pc.window);
      pc.window = AtlasWindow{};
      window_change = true;
    }
    if (!pc.window.valid()) {
      auto w = atlas_.allocate(wclass_p);
      if (!w && out.reclaim) w = allocate_or_reclaim(wclass_p, true);
      if (!w) {
        for (int q = 0; q < count; ++q)
          if (pcs[q].window.valid()) {
            atlas_.release(pcs[q].window);
            pcs[q].window = AtlasWindow{};
          }
        if (out.starved) {  // planned again at the end of the frame, when windows may be taken back
          out.starved->push_back(static_cast<std::uint32_t>(i));
          return PartsPlanned::kDeferred;
        }
        ++st.atlas_fallbacks;
        cs.valid = false;
        return PartsPlanned::kGeometry;
      }
      pc.window = *w;
      due[p] = true;
    }
  }
  if (all) ++st.new_snapshots;
  if (window_change && !all) ++st.window_refreshes;
  // Cards that must be refreshed now (new character, new window) whatever the budget.
  std::array<bool, kMaxBodyParts> must = due;
  std::array<float, kMaxBodyParts> staleness{};
  // Cache tests. Posture (section 5.1): each card against the character's posture when it was
  // taken (the cards of a character are taken together unless a refresh budget spreads them).
  // View (section 5.2), per card: a card reproduces any rotation of its part about the line of
  // sight (a roll of the picture) and any translation; what it cannot show is the part turning
  // out of the card's plane, so the test is the angle between the card's normal, carried by the
  // bone, and the current line of sight to the part.
  const CacheConfig& cc = config_.cache;
  const std::array<float, 4> posture = posture_at(bc, f0, f1, blend);
  const float w = distance_weight(cc, glm::distance(ta, camera.eye), pixels);
  // A limb card turns about the limb's axis to face the eye (the cylinder's picture does not
  // change); the view test then sees only the change of the angle between that axis and the line
  // of sight.
  for (int p = 0; p < count; ++p) {
    if (!turns[p] || must[p]) continue;
    const glm::vec3 n = glm::normalize(glm::mat3(bone[p]) * pcs[p].card_normal);
    const glm::vec3 los = glm::normalize(centre[p] - camera.eye);
    const glm::vec3 a = glm::normalize(glm::mat3(bone[p]) * parts[p].axis);
    const glm::vec3 nq = n - glm::dot(n, a) * a, lq = los - glm::dot(los, a) * a;  // across the axis
    if (glm::dot(nq, nq) > 1e-6f && glm::dot(lq, lq) > 1e-6f)
      turn[p] = glm::mat3(glm::rotate(glm::mat4(1.0f), std::atan2(glm::dot(a, glm::cross(nq, lq)), glm::dot(nq, lq)), a));
  }
  bool by_posture = false, by_view = false;
  const float vthr = std::min(glm::radians(cc.view_threshold_deg) * w, 3.14159265f);
  const float cthr = std::cos(vthr);
  // Leading cards (ImpostorConfig::lead_cards): the eye in the character's frame now, and its
  // velocity there since the previous planned frame.
  const bool lead = config_.lead_cards && cc.view_test && !config_.aligned_snapshots;
  glm::vec3 eye_char(0.0f), eye_vel(0.0f);
  if (lead) {
    eye_char = glm::vec3(glm::inverse(place) * glm::vec4(camera.eye, 1.0f));
    if (cs.eye_valid && time > cs.eye_time) eye_vel = (eye_char - cs.eye_char) / (time - cs.eye_time);
    cs.eye_char = eye_char;
    cs.eye_time = time;
    cs.eye_valid = true;
  }
  for (int p = 0; p < count; ++p) {
    if (must[p]) continue;
    if (cc.posture_test && posture_changed(pcs[p].posture, posture, cc.posture_threshold * w)) {
      due[p] = by_posture = true;
      staleness[p] = posture_staleness(pcs[p].posture, posture, cc.posture_threshold * w);
    }
    if (cc.view_test) {
      const glm::vec3 n = turn[p] * glm::normalize(glm::mat3(bone[p]) * pcs[p].card_normal);
      const glm::vec3 los = glm::normalize(centre[p] - camera.eye);
      float c = glm::dot(n, los);
      if (lead) c = std::min(c, glm::dot(turn[p] * glm::normalize(glm::mat3(bone[p]) * pcs[p].normal), los));
      // Threshold 0: any turn, as the sine measures it (a cosine rounds to 1 below 3e-4 radians),
      // above the 1e-6 radians that carrying the card's normal by its bone rounds to.
      if (c < cthr || (vthr <= 0.0f && glm::length(glm::cross(n, los)) > 1e-6f)) {
        by_view |= !due[p];
        due[p] = true;
        staleness[p] = std::max(staleness[p], std::acos(std::clamp(c, -1.0f, 1.0f)) / std::max(vthr, 1e-6f));
      }
    }
  }
  // ImpostorConfig::short_lived_as_geometry: geometry when at least half the cards are due one
  // frame after their snapshots (the cards' state moves on every frame), and all its cards taken
  // anew at the first frame where fewer are.
  if (config_.short_lived_as_geometry && !all && cc.refresh_budget <= 0) {
    const std::uint32_t frame = frame_.setup.frame;
    int young = 0;
    for (int p = 0; p < count; ++p) young += due[p] && !must[p] && pcs[p].taken + 1 == frame;
    if (young > 0 && 2 * young >= count) {
      for (int p = 0; p < count; ++p) {  // each card's state moves on as if it had been taken
        const glm::vec3 los(glm::inverse(bone[p]) * glm::vec4(glm::normalize(centre[p] - camera.eye), 0.0f));
        pcs[p].normal = pcs[p].card_normal = los;
        pcs[p].posture = posture;
        pcs[p].taken = frame;
      }
      cs.picture_behind = true;
      ++st.short_lived_geometry;
      return PartsPlanned::kGeometry;
    }
  }
  if (cs.picture_behind) {  // the windows hold older pictures
    for (int p = 0; p < count; ++p) due[p] = must[p] = true;
    cs.picture_behind = false;
  }
  if (by_posture) ++st.posture_refreshes;
  if (by_view) ++st.view_refreshes;
  cs.valid = true;
  // New cards: into the cache now, or, with a refresh budget and stale cards, into pending_parts_
  // (the old card is drawn meanwhile).
  const bool budget = cc.refresh_budget > 0;
  const int lods = static_cast<int>(m.lods.size());
  const int slod = config_.snapshot_lod_from_screen
                       ? std::min(lod_for(pixels, camera.height), lods - 1)
                       : lod_for(static_cast<float>(config_.windows.size[pcs[0].window.size_class]), camera.height);
  const int clip = static_cast<int>(&bc - m.baked_clips().data());
  bool refreshed = false;
  for (int p = 0; p < count; ++p) {
    PartCache& pc = pcs[p];
    const AtlasWindow& win = pc.window;
    if (due[p]) {
      const PartJob job{static_cast<std::uint32_t>(i), p, bone[p], centre[p], depth[p], inst, posture, slod, clip,
                        lead, eye_char, eye_vel, cthr};
      if (budget && !must[p]) {
        // Stale: its old card is drawn; the budget may reach it in end_frame, which works its
        // card out then (most stale cards wait).
        out.pending_parts->push_back(PendingPart{staleness[p], static_cast<std::uint32_t>(i * parts_ + p),
                                                 static_cast<std::uint32_t>(out.billboards->size()),
                                                 static_cast<std::uint32_t>(out.part_jobs->size())});
        out.part_jobs->push_back(job);
      } else {
        std::size_t tris = 0;
        SnapshotGpu s;
        pc = part_card(job, ch, s, tris);
        turn[p] = glm::mat3(1.0f);
        out.snapshots.add(slod, s);
        ++st.part_snapshots;
        st.snapshot_triangles += tris;
        ++*out.budget_used;
        refreshed = true;
      }
    }
    out.billboards->push_back(part_billboard(pc, bone[p], turn[p]));
    ++st.impostors_per_window[win.size_class];
    ++st.part_cards;
    st.quad_texels += rect_texels(pc.rect, win.size);
  }
  if (refreshed) {
    ++st.snapshots;
    refreshed_[i] = 1;
  }
  ++st.impostors;
  return PartsPlanned::kCards;
}

}  // namespace bb::runtime
