#include "bb/runtime/impostor.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

#include <glm/gtc/matrix_transform.hpp>

namespace bb::runtime {

glm::vec3 SceneCamera::view_up() const {
  // glm::lookAt's right axis is cross(forward, up): none where they are parallel (a camera looking
  // straight down with up +Y), and the view matrix would be NaN.
  const glm::vec3 f = target - eye;
  auto across = [&f](const glm::vec3& u) {
    return glm::length(glm::cross(f, u)) > 1e-6f * glm::length(f) * glm::length(u);
  };
  if (across(up)) return up;
  return across(glm::vec3(0.0f, 0.0f, 1.0f)) ? glm::vec3(0.0f, 0.0f, 1.0f) : glm::vec3(1.0f, 0.0f, 0.0f);
}

glm::mat4 SceneCamera::view() const { return glm::lookAt(eye, target, view_up()); }

glm::mat4 SceneCamera::projection() const {
  return glm::perspective(fov_y, static_cast<float>(width) / static_cast<float>(std::max(1, height)), near_plane,
                          far_plane);
}

float SceneCamera::pixels_per_metre(float depth) const {
  return 0.5f * static_cast<float>(height) / (std::tan(0.5f * fov_y) * std::max(depth, 1e-4f));
}

glm::mat4 SnapshotCamera::view() const {
  // Rows: Ho, Uo, -Vo (camera looks down -Z).
  glm::mat4 v(1.0f);
  v[0][0] = ho.x; v[1][0] = ho.y; v[2][0] = ho.z;
  v[0][1] = uo.x; v[1][1] = uo.y; v[2][1] = uo.z;
  v[0][2] = -vo.x; v[1][2] = -vo.y; v[2][2] = -vo.z;
  v[3][0] = -glm::dot(ho, to);
  v[3][1] = -glm::dot(uo, to);
  v[3][2] = glm::dot(vo, to);
  return v;
}

glm::mat4 SnapshotCamera::projection() const {
  const float n = std::max(distance - radius, 0.01f * distance), f = distance + radius;
  if (perspective) {
    const float k = n / distance;
    return glm::frustum((offset.x - half_size) * k, (offset.x + half_size) * k, (offset.y - half_size) * k,
                        (offset.y + half_size) * k, n, f);
  }
  return glm::ortho(-half_size, half_size, -half_size, half_size, n, f);
}

SnapshotCamera make_snapshot_camera(const glm::vec3& ta, const glm::vec3& eye, const glm::vec3& up, float radius,
                                    float distance, bool perspective) {
  SnapshotCamera c;
  c.ta = ta;
  c.radius = radius;
  c.half_size = radius;
  c.distance = distance > 0.0f ? distance : 2.0f * radius;
  glm::vec3 v = ta - eye;
  float l = glm::length(v);
  if (perspective && l > 1.05f * radius) {
    c.perspective = true;
    c.distance = l;
    c.half_size = radius * l / std::sqrt(l * l - radius * radius);
  }
  c.vo = l > 0.0f ? v / l : glm::vec3(0, 0, -1);
  glm::vec3 h = glm::cross(c.vo, up);
  float hl = glm::length(h);
  if (!(hl > 1e-6f)) {  // looking along the up vector: any horizontal right vector will do
    h = glm::cross(c.vo, glm::vec3(0, 0, 1));
    if (glm::length(h) < 1e-6f) h = glm::vec3(1, 0, 0);
    hl = glm::length(h);
  }
  c.ho = h / hl;
  c.uo = glm::cross(c.ho, c.vo);
  c.to = ta - c.distance * c.vo;
  return c;
}

void camera_axes(const SceneCamera& camera, glm::vec3& right, glm::vec3& up, glm::vec3& forward) {
  const glm::mat4 v = camera.view();
  right = glm::vec3(v[0][0], v[1][0], v[2][0]);
  up = glm::vec3(v[0][1], v[1][1], v[2][1]);
  forward = -glm::vec3(v[0][2], v[1][2], v[2][2]);
}

namespace {
// Half extent of the interval of tangents tan(a +- b) around tan(a), where a is the direction of
// the centre (lateral x, depth z > 0) and b the half angle the sphere subtends (sin b = r / l).
// By the tangent sums, tan(a +- b) = (t +- u) / (1 -+ t u) with t = x / z and u = tan b =
// r / sqrt(l^2 - r^2): no trigonometric call (the planner asks this of every character every
// frame: RiggedSimple, 10,000 humans, planning 1.45-1.89 ms with atan2, asin and three tangents a
// call, 1.09-1.10 ms without; 0.84 ms on the free grid, which does not ask). Infinite where the
// sphere reaches 90 degrees off the axis on that side.
float tangent_half_extent(float x, float z, float r) {
  const float l2 = x * x + z * z, d2 = l2 - r * r;
  if (!(d2 > 0.0f)) return std::numeric_limits<float>::infinity();
  const float t = x / z, u = r / std::sqrt(d2);
  const float hi = 1.0f - t * u, lo = 1.0f + t * u;
  if (!(hi > 0.0f) || !(lo > 0.0f)) return std::numeric_limits<float>::infinity();
  return std::max((t + u) / hi - t, t - (t - u) / lo);
}
}  // namespace

float aligned_pixels(const SceneCamera& camera, const glm::vec3& centre, float radius) {
  glm::vec3 right, up, fwd;
  camera_axes(camera, right, up, fwd);
  return aligned_pixels(camera.eye, right, up, fwd, camera.pixels_per_metre(1.0f), centre, radius);
}

float aligned_pixels(const glm::vec3& eye, const glm::vec3& right, const glm::vec3& up, const glm::vec3& fwd,
                     float ppm1, const glm::vec3& centre, float radius) {
  const glm::vec3 v = centre - eye;
  const float z = glm::dot(v, fwd);
  if (!(z > 1.05f * radius) || !(glm::length(v) > 1.05f * radius)) return std::numeric_limits<float>::infinity();
  const float hx = tangent_half_extent(glm::dot(v, right), z, radius);
  const float hy = tangent_half_extent(glm::dot(v, up), z, radius);
  return 2.0f * ppm1 * std::max(hx, hy);
}

std::optional<SnapshotCamera> make_aligned_snapshot_camera(const SceneCamera& camera, const glm::vec3& centre,
                                                           float radius, int window_texels, float texels_per_pixel,
                                                           float phase) {
  assert(phase >= 0.0f && phase < 1.0f && "ImpostorConfig::aligned_phase: pixels, 0 <= phase < 1");
  glm::vec3 right, up, fwd;
  camera_axes(camera, right, up, fwd);
  if (!(texels_per_pixel > 0.0f) ||
      aligned_pixels(camera.eye, right, up, fwd, camera.pixels_per_metre(1.0f), centre, radius) * texels_per_pixel > window_texels)
    return std::nullopt;
  const glm::vec3 v = centre - camera.eye;
  const float z = glm::dot(v, fwd);
  const float ppm = camera.pixels_per_metre(z);  // at the centre's depth
  // The centre's projection in pixels from the lower-left corner of the viewport, snapped to the
  // nearest point `phase` right of and above a pixel corner.
  const glm::vec2 half_view(0.5f * static_cast<float>(camera.width), 0.5f * static_cast<float>(camera.height));
  const glm::vec2 px = half_view + ppm * glm::vec2(glm::dot(v, right), glm::dot(v, up));
  const glm::vec2 snapped = glm::round(px - phase) + phase;
  const glm::vec2 lateral = (snapped - half_view) / ppm;  // the window centre, metres from the axis
  SnapshotCamera c;
  c.perspective = true;
  c.ho = right;
  c.uo = up;
  c.vo = fwd;
  c.distance = z;
  c.offset = lateral;
  c.to = camera.eye;
  c.ta = camera.eye + z * fwd + lateral.x * right + lateral.y * up;
  c.radius = radius;
  c.half_size = 0.5f * static_cast<float>(window_texels) / (texels_per_pixel * ppm);
  return c;
}

glm::mat3 view_rotation(const SnapshotCamera& cam, float yaw) {
  // Character rotation R = rotY(yaw); R^T applied to each column.
  const float c = std::cos(yaw), s = std::sin(yaw);
  auto inv = [&](const glm::vec3& v) { return glm::vec3(c * v.x - s * v.z, v.y, s * v.x + c * v.z); };
  return glm::mat3(inv(cam.ho), inv(cam.uo), inv(-cam.vo));
}

float rotation_angle(const glm::mat3& a, const glm::mat3& b) {
  return std::acos(std::clamp(rotation_cosine(a, b), -1.0f, 1.0f));
}

int choose_window(const WindowSizes& sizes, float pixels) {
  int best = 0;
  for (int i = 0; i < sizes.count; ++i)
    if (static_cast<float>(sizes.size[i]) >= pixels) best = i;  // sizes decrease with i
  return best;
}

AtlasAllocator::AtlasAllocator(int page_size, int max_pages, const WindowSizes& sizes, int first_page)
    : page_size_(page_size), first_page_(std::max(0, first_page)), sizes_(sizes), pages_(static_cast<std::size_t>(std::max(1, max_pages))) {
  assert(sizes.count >= 1 && sizes.count <= 8 && sizes.size[0] <= page_size);
  sizes_.count = std::clamp(sizes_.count, 1, static_cast<int>(sizes_.size.size()));
  for (auto& v : open_pages_) v.reserve(pages_.size());
}

std::optional<AtlasWindow> AtlasAllocator::allocate(int size_class) {
  assert(size_class >= 0 && size_class < sizes_.count);
  auto& open = open_pages_[size_class];
  int p = -1;
  if (!open.empty()) {
    p = open.back();
  } else {
    for (std::size_t i = 0; i < pages_.size(); ++i)
      if (pages_[i].size_class < 0) {
        p = static_cast<int>(i);
        break;
      }
    if (p < 0) return std::nullopt;
    // A page holds no window larger than itself (ImpostorConfig's contract, which
    // validate_impostor_config checks): nothing to hand out rather than a page of no slots.
    assert(sizes_.size[size_class] >= 1 && sizes_.size[size_class] <= page_size_);
    if (sizes_.size[size_class] < 1 || sizes_.size[size_class] > page_size_) return std::nullopt;
    Page& pg = pages_[p];
    pg.size_class = size_class;
    pg.per_row = page_size_ / sizes_.size[size_class];
    const int n = pg.per_row * pg.per_row;
    pg.free_slots.resize(n);
    for (int i = 0; i < n; ++i) pg.free_slots[i] = n - 1 - i;  // hand out slot 0 first
    pg.used = 0;
    open.push_back(p);
  }
  Page& pg = pages_[p];
  const std::int32_t slot = pg.free_slots.back();
  pg.free_slots.pop_back();
  ++pg.used;
  ++windows_used_;
  if (pg.free_slots.empty()) open.erase(std::find(open.begin(), open.end(), p));
  AtlasWindow w;
  w.page = first_page_ + p;
  w.size = sizes_.size[size_class];
  w.size_class = size_class;
  w.slot = slot;
  w.x = (slot % pg.per_row) * w.size;
  w.y = (slot / pg.per_row) * w.size;
  return w;
}

void AtlasAllocator::release(const AtlasWindow& w) {
  const int p = w.page - first_page_;
  assert(w.valid() && p >= 0 && p < static_cast<int>(pages_.size()));
  Page& pg = pages_[static_cast<std::size_t>(p)];
  assert(pg.size_class == w.size_class);
  auto& open = open_pages_[w.size_class];
  if (pg.free_slots.empty()) open.push_back(p);
  pg.free_slots.push_back(w.slot);
  --pg.used;
  --windows_used_;
  if (pg.used == 0) {  // give the page back to every class
    pg.size_class = -1;
    pg.free_slots.clear();
    open.erase(std::find(open.begin(), open.end(), p));
  }
}

void AtlasAllocator::clear() {
  for (auto& p : pages_) p = Page{};
  for (auto& v : open_pages_) v.clear();
  windows_used_ = 0;
}

int AtlasAllocator::pages_used() const {
  int n = 0;
  for (const auto& p : pages_) n += p.size_class >= 0;
  return n;
}

float AtlasAllocator::pixel_use() const {
  double used = 0, total = 0;
  for (const auto& p : pages_) {
    if (p.size_class < 0) continue;
    total += static_cast<double>(page_size_) * page_size_;
    used += static_cast<double>(p.used) * sizes_.size[p.size_class] * sizes_.size[p.size_class];
  }
  return total > 0 ? static_cast<float>(used / total) : 0.0f;
}

}  // namespace bb::runtime
