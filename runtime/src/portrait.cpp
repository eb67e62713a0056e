#include "bb/runtime/portrait.h"

#include <algorithm>
#include <cmath>

#include "bb/runtime/renderer.h"

namespace bb::runtime {

SceneCamera portrait_camera(const Model& model, const PortraitOptions& o) {
  SceneCamera cam;
  cam.fov_y = glm::radians(o.fov_y_deg);
  cam.width = o.width;
  cam.height = o.height;
  float dist = o.distance > 0.0f ? o.distance : model.radius / std::tan(0.5f * cam.fov_y) / 0.9f;
  const float az = glm::radians(o.azimuth_deg), el = glm::radians(o.elevation_deg);
  const glm::vec3 ta = character_ta(model, Character{glm::vec3(0.0f), 0.0f, 1.0f, o.clip, 0.0f, 1.0f}, o.time);
  cam.target = ta;
  cam.eye = ta + dist * glm::vec3(std::sin(az) * std::cos(el), std::sin(el), std::cos(az) * std::cos(el));
  cam.near_plane = std::max(0.01f, 0.05f * dist);
  cam.far_plane = dist + 10.0f * model.radius + 10.0f;
  return cam;
}

namespace {

// The impostor configuration of a portrait: one window of the character's on-screen size.
ImpostorConfig portrait_config(const Model& model, const PortraitOptions& o, const SceneCamera& cam, int* window_out) {
  ImpostorConfig cfg;
  // One texel per pixel: the window is the character's on-screen size (even, so that with Ta at
  // the centre of an even-sized image the texels fall on the pixels).
  const float depth = glm::distance(cam.eye, cam.target), r = model.radius;
  const float half = depth > 1.05f * r ? r * depth / std::sqrt(depth * depth - r * r) : r;
  int window = static_cast<int>(std::ceil(2.0f * half * cam.pixels_per_metre(depth) - 1e-3f));
  window = std::clamp(window + (window & 1), 8, 4096);
  cfg.texel_per_pixel = true;
  cfg.texels_per_pixel = 1.0f;
  if (o.orthographic) {
    cfg.perspective_snapshots = false;
    window = std::clamp(static_cast<int>(std::ceil(2.0f * r * cam.pixels_per_metre(depth))), 8, 4096);
  }
  cfg.windows.count = 1;
  cfg.windows.size[0] = window;
  cfg.page_size = window;
  cfg.max_pages = 1;
  *window_out = window;
  return cfg;
}

}  // namespace

struct PortraitRenderer::State {
  int width = 0, height = 0, window = 0;
  bool orthographic = false;
  ImpostorConfig cfg;
  std::unique_ptr<Renderer> renderer;
  std::unique_ptr<OffscreenTarget> target;
};

PortraitRenderer::PortraitRenderer(const Model& model) : model_(model) {}
PortraitRenderer::~PortraitRenderer() = default;

Result<Image> PortraitRenderer::render(const PortraitOptions& o) {
  const SceneCamera cam = portrait_camera(model_, o);
  int window = 0;
  ImpostorConfig cfg = portrait_config(model_, o, cam, &window);
  if (!state_ || state_->width != o.width || state_->height != o.height || state_->window != window ||
      state_->orthographic != o.orthographic) {
    state_.reset();
    auto s = std::make_unique<State>();
    s->width = o.width;
    s->height = o.height;
    s->window = window;
    s->orthographic = o.orthographic;
    s->cfg = cfg;
    auto renderer = Renderer::create(model_, cfg);
    if (!renderer) return renderer.error();
    s->renderer = std::move(*renderer);
    auto target = OffscreenTarget::create(o.width, o.height);
    if (!target) return target.error();
    s->target = std::move(*target);
    state_ = std::move(s);
    ++setups_;
  }
  Crowd crowd(model_);
  crowd.add(Character{glm::vec3(0.0f), 0.0f, 1.0f, o.clip, 0.0f, 1.0f});
  // A planner of its own per picture: its cache starts empty, so an impostor is always snapshot now.
  FramePlanner planner(model_, state_->cfg);
  const FramePlan& plan = planner.plan(crowd, cam, o.time, o.mode == RenderMode::kGeometry ? RenderMode::kGeometry : RenderMode::kImpostor);
  state_->target->bind(true);
  DrawOptions draw;
  draw.edges = ImpostorEdges::kCentre;  // texels on pixels: the impostor is the snapshot, exactly
  state_->renderer->draw(plan, draw);
  Image img;
  img.width = o.width;
  img.height = o.height;
  img.rgba = state_->target->read_rgba();
  img.stats = plan.stats;
  img.window_pixels = window;
  return img;
}

Result<Image> render_portrait(const Model& model, const PortraitOptions& o) { return PortraitRenderer(model).render(o); }

}  // namespace bb::runtime
