#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cctype>
#include <limits>
#include <memory>
#include <span>
#include <utility>
#include <vector>

#include "bb/runtime/renderer.h"
#include "flow.h"
#include "image_metrics.h"

namespace bb::cli {

namespace {

using Clock = std::chrono::steady_clock;

struct Walker {
  float radius, omega, theta0, speed;
  int dir;
};

int choose_clip(const runtime::Model& model, const std::string& wanted) {
  if (!wanted.empty()) return std::max(0, model.find_clip(wanted));  // the CLI checked that it exists
  for (size_t i = 0; i < model.clips.size(); ++i) {
    std::string n = model.clips[i].name;
    std::transform(n.begin(), n.end(), n.begin(), [](unsigned char c) { return std::tolower(c); });
    if (n.find("walk") != std::string::npos) return static_cast<int>(i);
  }
  for (size_t i = 0; i < model.clips.size(); ++i)  // else the first clip that walks (BakedClip::ground_speed)
    if (model.baked_clips()[i].ground_speed > 0.0f) return static_cast<int>(i);
  return 0;
}

// "walk_1.20mps" -> 1.2; 0 when the name carries no speed.
float speed_from_name(const std::string& name) {
  auto p = name.find("mps");
  if (p == std::string::npos) return 0;
  size_t b = p;
  while (b > 0 && (std::isdigit(static_cast<unsigned char>(name[b - 1])) || name[b - 1] == '.')) --b;
  if (b == p) return 0;
  return std::strtof(name.substr(b, p - b).c_str(), nullptr);
}

// 95th percentile (nearest rank), worst and standard deviation of per-frame times.
FlowResult::Spread spread(std::vector<double> t) {
  FlowResult::Spread s;
  if (t.empty()) return s;
  double mean = 0;
  for (double v : t) mean += v;
  mean /= static_cast<double>(t.size());
  double var = 0;
  for (double v : t) var += (v - mean) * (v - mean);
  s.sd = std::sqrt(var / static_cast<double>(t.size()));
  std::sort(t.begin(), t.end());
  s.max = t.back();
  const std::size_t n = t.size();
  s.median = n % 2 ? t[n / 2] : 0.5 * (t[n / 2 - 1] + t[n / 2]);
  const std::size_t rank = static_cast<std::size_t>(std::ceil(0.95 * static_cast<double>(t.size())));
  s.p95 = t[std::clamp<std::size_t>(rank, 1, t.size()) - 1];
  return s;
}

// The screen box (pixels, top-left origin) of world points; false where one lies behind the eye.
bool screen_box(std::span<const glm::vec3> points, const glm::mat4& vp, const runtime::SceneCamera& cam, glm::vec4* box) {
  *box = glm::vec4(1e30f, 1e30f, -1e30f, -1e30f);
  for (const glm::vec3& p : points) {
    const glm::vec4 c = vp * glm::vec4(p, 1.0f);
    if (c.w <= 1e-6f) return false;
    const float x = (c.x / c.w * 0.5f + 0.5f) * static_cast<float>(cam.width);
    const float y = (0.5f - c.y / c.w * 0.5f) * static_cast<float>(cam.height);
    *box = {std::min(box->x, x), std::min(box->y, y), std::max(box->z, x), std::max(box->w, y)};
  }
  return true;
}

// What the impostor path refreshed in a frame, as screen boxes: each snapshot's planned quad (in its
// window, around Ta along Ho and Uo) projected, and
// each character drawn as geometry in place of a snapshot that would have been drawn once
// (ImpostorConfig::short_lived_as_geometry): the box of its model's poses where it stands.
// plans[m] is models[m]'s.
std::vector<glm::vec4> refreshed_boxes(std::span<const runtime::FramePlan* const> plans,
                                       std::span<const runtime::Model* const> models, const runtime::SceneCamera& cam) {
  std::vector<glm::vec4> out;
  const glm::mat4 vp = cam.projection() * cam.view();
  glm::vec4 box;
  for (std::size_t m = 0; m < plans.size(); ++m) {
    const runtime::FramePlan& plan = *plans[m];
    for (const auto& level : plan.snapshots)
      for (const runtime::SnapshotGpu& sp : level) {
        const glm::vec3 ta(sp.ta), ho(sp.ho_half), uo(sp.uo_dist);
        const float half = sp.ho_half.w;
        std::array<glm::vec3, 4> corners;
        for (int k = 0; k < 4; ++k) {
          const float qx = (k & 1) ? sp.quad.z : sp.quad.x, qy = (k & 2) ? sp.quad.w : sp.quad.y;
          corners[k] = ta + half * (qx * ho + qy * uo);
        }
        if (screen_box(corners, vp, cam, &box)) out.push_back(box);
      }
    // Only where every character the plan draws as geometry is one of these (a planner may also
    // draw a character as geometry for other reasons, which are no refresh).
    if (plan.stats.short_lived_geometry == 0 || plan.stats.geometry != plan.stats.short_lived_geometry) continue;
    const glm::vec3 lo = models[m]->bounds_min, hi = models[m]->bounds_max;
    for (const auto& level : plan.geometry)
      for (const runtime::InstanceGpu& in : level) {
        // The geometry shader's placement: scaled, turned by the yaw about +Y, moved.
        const float c = std::cos(in.position_yaw.w), sn = std::sin(in.position_yaw.w), sc = in.anim.x;
        std::array<glm::vec3, 8> corners;
        for (int k = 0; k < 8; ++k) {
          const glm::vec3 p = sc * glm::vec3((k & 1) ? hi.x : lo.x, (k & 2) ? hi.y : lo.y, (k & 4) ? hi.z : lo.z);
          corners[k] = glm::vec3(in.position_yaw) + glm::vec3(c * p.x + sn * p.z, p.y, -sn * p.x + c * p.z);
        }
        if (screen_box(corners, vp, cam, &box)) out.push_back(box);
      }
  }
  return out;
}

}  // namespace

std::size_t part_triangles(const runtime::Model& m) {
  return m.body_parts().size() < 2 ? 0 : runtime::snapshot_triangles(m, true);
}

runtime::ImpostorEdges edges_of(const std::string& impostor_edges) {
  using runtime::ImpostorEdges;
  return impostor_edges == "coverage"  ? ImpostorEdges::kAlphaToCoverage
         : impostor_edges == "test"    ? ImpostorEdges::kAlphaTest
         : impostor_edges == "samples" ? ImpostorEdges::kSamples
         : impostor_edges == "centre"  ? ImpostorEdges::kCentre
                                       : ImpostorEdges::kBlend;
}

Result<FlowResult> run_flow(const runtime::Model& model, const FlowSettings& s, const std::string& device) {
  const runtime::Model* one[1] = {&model};
  return run_flow(std::span<const runtime::Model* const>(one), s, device);
}

Result<FlowResult> run_flow(std::span<const runtime::Model* const> models, const FlowSettings& s,
                            const std::string& device) {
  using namespace runtime;
  if (models.empty()) return Error{"", "flow", "no model"};
  const int nm = static_cast<int>(models.size());
  const Model& model = *models[0];
  FlowResult out;
  out.humans = s.humans;
  out.frames = s.frames;
  out.width = s.width;
  out.height = s.height;
  out.device = device;
  if (s.part_cards)
    for (const auto& p : model.body_parts()) out.parts.push_back(model.nodes[model.palette[p.bone].node].name);

  ImpostorConfig config;
  config.cache.posture_test = s.posture_test;
  config.cache.posture_threshold = s.posture_threshold;
  config.cache.view_test = s.view_test;
  config.cache.view_threshold_deg = s.view_deg;
  config.cache.distance_weighting = s.distance_weighting;
  config.cache.reference_pixels = s.screen_weighting_px;
  config.texels_per_pixel = s.texels_per_pixel;
  config.windows = s.windows;
  config.snapshot_lod_from_screen = s.snapshot_lod_from_screen;
  config.perspective_snapshots = s.perspective_snapshots;
  config.part_cards = s.part_cards;
  config.turn_limb_cards = s.turn_limb_cards;
  config.parallax_cards = s.parallax_cards;
  config.relight = s.relight;
  config.parallax_depth_pass = s.parallax_depth_pass;
  config.lead_cards = s.lead_cards;
  config.view_lead = s.view_lead;
  config.texel_per_pixel = s.exact_scale;
  config.snapshot_samples = s.snapshot_samples;
  config.fit_quads_to_coverage = s.fit_quads;
  // auto: the CPU's fit from the vertices on a software rasterizer, where the coverage pass's barrier
  // finishes the frame's drawing so far (flow test bed, llvmpipe: part cards at 8 degrees 3.70-4.06x
  // against 3.27-3.65x with the pass, at 1,000 humans 3.65-3.75x against 3.32-3.40x; RiggedSimple
  // orbiting at 17 degrees 4.68-4.93x against 4.52-4.62x; our four bodies' main run, worst case and
  // 1,000 humans the same or faster; the same pictures), but not for depth-corrected cards, which keep
  // the pass for their wide offsets and were slower with both (2.32x against 2.44-2.52x). On the H200
  // the fit's planning made the frames slower (20 humans 0.62-0.69x against 0.76x, part cards 0.22x
  // against 0.27-0.28x), so a GPU keeps the pass.
  const bool software = software_rasterizer();
  TuningScene scene;
  scene.samples = s.msaa;
  scene.software = software;
  scene.edges = edges_of(s.impostor_edges);
  // The grid, the taps and the phase (flow's --snapshot-grid and --impostor-taps, auto: tuned for
  // this rasterizer), in the order the tuned_* functions read them.
  config.aligned_snapshots = s.aligned_snapshots < 0 ? tuned_aligned_snapshots(config, scene) : s.aligned_snapshots > 0;
  config.impostor_taps = s.impostor_taps > 0 ? s.impostor_taps : tuned_impostor_taps(config, scene);
  config.aligned_phase = tuned_aligned_phase(config, scene);
  out.aligned_snapshots = config.aligned_snapshots;
  out.impostor_taps = config.impostor_taps;
  out.aligned_phase = config.aligned_phase;
  config.fit_quads_from_vertices =
      s.fit_quads && (s.fit_from_vertices > 0 || (s.fit_from_vertices < 0 && tuned_fit_from_vertices(config, scene)));
  out.fit_from_vertices = config.fit_quads_from_vertices;
  config.coverage_group = s.coverage_group;
  config.quad_fetch = s.quad_fetch;
  config.planner_threads = s.planner_threads;
  DrawOptions draw_options;
  draw_options.time_stages = s.time_stages;
  draw_options.flush_every_indices = s.flush_every_indices;
  draw_options.edges = edges_of(s.impostor_edges);
  // Impostor frames hold impostors only, and blended edges need no multisampled target (auto on a
  // software rasterizer). A character drawn as geometry in an impostor frame in place of a
  // short-lived snapshot (below) needs the scene's samples to be the geometry path's own picture:
  // adaptive (auto on a GPU) draws the impostor frame into a target of the scene's samples after a
  // frame that drew such a character, else into the single-sampled one.
  const int blend_samples = impostor_target_samples(draw_options.edges, s.msaa);
  // A model of so few triangles that drawing a character costs less than its snapshot
  // (kFewTriangles) draws its short-lived characters as geometry on a software rasterizer too, so
  // auto takes the adaptive target there for a crowd with such a model.
  // A snapshot's triangles: a character's, or with part cards a card's (runtime::snapshot_triangles).
  auto triangles_of = [&](int m) { return snapshot_triangles(*models[m], s.part_cards); };
  auto few_triangles = [&](int m) { return triangles_of(m) > 0 && triangles_of(m) < kFewTriangles; };
  bool few = false;
  for (int m = 0; m < nm; ++m) few |= few_triangles(m);
  // Adaptive as asked (or auto on a GPU), and for such a crowd.
  const bool adaptive_asked =
      blend_samples < s.msaa && (s.impostor_target_samples < 0 || (s.impostor_target_samples == 0 && !software));
  const bool adaptive = adaptive_asked || (blend_samples < s.msaa && s.impostor_target_samples == 0 && few);
  const int samples_i = s.impostor_target_samples > 0 ? s.impostor_target_samples : blend_samples;
  // auto: where a character drawn as geometry in an impostor frame is the geometry path's own
  // picture (the impostor target has the scene's samples, or adaptive), and a snapshot costs what
  // drawing the character does or more: in a single-sampled scene, and on a GPU. On the H200 the
  // worst case (both thresholds 0, 4x) went from 0.45 / 0.56 / 0.65x of geometry's speed at 20 /
  // 1,000 / 5,000 humans to 1.03 / 0.95 / 0.96x adaptive, the snapshot pass taking the GPU 1.5 times what
  // the same triangles take in the scene. On llvmpipe a 4x scene's single-sampled snapshot is the
  // cheaper (4x, --impostor-target scene, both thresholds 0: 0.63 of the geometry's time with
  // snapshots, 0.98-1.00 with geometry).
  scene.impostor_samples = samples_i;
  scene.adaptive_target = adaptive;
  // Each model's (configs_for): a model of few triangles (kFewTriangles) draws them as geometry
  // wherever that is the geometry's own picture; the others as they would without it in the crowd
  // (the target adaptive only as asked).
  TuningScene scene_asked = scene;
  scene_asked.adaptive_target = adaptive_asked;
  auto short_lived_of = [&](int m) {
    const TuningScene& sc = few_triangles(m) ? scene : scene_asked;
    return s.short_lived > 0 || (s.short_lived < 0 && tuned_short_lived_as_geometry(sc, triangles_of(m)));
  };
  bool any_short_lived = false;
  for (int m = 0; m < nm; ++m) any_short_lived |= short_lived_of(m);
  out.short_lived_as_geometry = any_short_lived && s.refresh_budget == 0;
  // One renderer, planner and crowd per model; human i is of model i % models.size().
  std::vector<std::unique_ptr<Renderer>> renderers;
  std::vector<Renderer*> renderer_ptrs;  // the same, for Renderer::draw_many
  std::vector<std::unique_ptr<FramePlanner>> planners;
  std::vector<Crowd> crowds;
  // Enough atlas for each model's share of the crowd: windows of 256 px, 16 per 1024 page; with
  // --atlas shared (the default) the models' pages are parts of one atlas, one after another.
  auto humans_of = [&](int m) { return (s.humans + nm - 1 - m) / nm; };
  auto pages_of = [&](int m) { return std::clamp(humans_of(m) / 8 + 4, 8, 64); };
  // The models' configs, with one atlas for all or an atlas each.
  auto configs_for = [&](bool share) {
    int shared_pages = 0;
    for (int m = 0; m < nm; ++m) shared_pages += pages_of(m);
    std::vector<ImpostorConfig> cs;
    for (int m = 0, first_page = 0; m < nm; ++m) {
      ImpostorConfig c = config;
      c.short_lived_as_geometry = short_lived_of(m);
      c.max_pages = pages_of(m);
      c.first_page = share ? first_page : 0;
      c.atlas_pages = share ? shared_pages : 0;
      first_page += c.max_pages;
      // The refresh budget is the crowd's: each model's planner gets its share (at least one).
      c.cache.refresh_budget =
          s.refresh_budget > 0 ? std::max(1, s.refresh_budget / nm + (m < s.refresh_budget % nm ? 1 : 0)) : 0;
      c.cache.ahead_fraction = s.refresh_ahead;
      c.cache.ahead_count = s.ahead_count;
      cs.push_back(c);
    }
    return cs;
  };
  // Where one atlas for all is more than the GL makes in one texture (llvmpipe: 2 GB, 512 pages of
  // 1024: eight models at 10,000 humans share one, nine do not), the models take an atlas each.
  bool share = s.shared_atlas && nm > 1;
  std::vector<ImpostorConfig> configs = configs_for(share);
  auto made = Renderer::create(*models[0], configs[0]);  // it makes the atlas
  if (!made && share) {  // the shared atlas's texture was refused: an atlas each
    share = false;
    configs = configs_for(false);
    made = Renderer::create(*models[0], configs[0]);
  }
  out.shared_atlas = share || nm == 1;
  for (int m = 0; m < nm; ++m) {
    if (m > 0) made = Renderer::create(*models[m], configs[m], share ? renderers.front().get() : nullptr);
    if (!made) return made.error();
    renderers.push_back(std::move(*made));
    renderer_ptrs.push_back(renderers.back().get());
  }
  out.coverage_group = renderers.front()->coverage_group();
  out.pulled_quads = renderers.front()->pulls_quads();
  for (int m = 0; m < nm; ++m) {
    planners.push_back(std::make_unique<FramePlanner>(*models[m], configs[m]));
    crowds.emplace_back(*models[m]);
    crowds.back().reserve(static_cast<std::size_t>(humans_of(m)));
  }
  std::vector<FramePlanner*> planner_ptrs;
  std::vector<const Crowd*> crowd_ptrs;
  for (int m = 0; m < nm; ++m) {
    planner_ptrs.push_back(planners[m].get());
    crowd_ptrs.push_back(&crowds[m]);
  }
  auto target_g = OffscreenTarget::create(s.width, s.height, s.msaa);
  if (!target_g) return target_g.error();
  auto target_i = OffscreenTarget::create(s.width, s.height, samples_i);
  if (!target_i) return target_i.error();
  std::unique_ptr<OffscreenTarget> target_ims;  // adaptive: the scene's samples
  if (adaptive) {
    auto t = OffscreenTarget::create(s.width, s.height, s.msaa);
    if (!t) return t.error();
    target_ims = std::move(*t);
  }
  out.geometry_target_samples = (*target_g)->samples();
  out.impostor_target_samples = (*target_i)->samples();
  out.impostor_target_adaptive = adaptive;
  int last_short_lived = 0;  // characters the last impostor frame drew as geometry (adaptive)
  int multisampled_frames = 0;

  // The crowd: concentric circles, a few humans per circle, speeds 0.6 .. 1.8 m/s, alternate
  // directions. Circles are spaced so that neighbours do not collide.
  // Each model walks its own walk clip, played at the rate that matches its walker's speed: the
  // speed its name gives ("walk_1.20mps"), else the one measured from its poses
  // (BakedClip::ground_speed); a clip that does not walk plays at its own rate.
  // A model whose height is not within a factor of 2 of the
  // first model's (another unit: the Fox is in centimetres) is scaled to the first one's height;
  // the others keep theirs (our body's variants differ in height on purpose). The scene is scaled
  // to the largest character.
  std::vector<int> clips(static_cast<std::size_t>(nm));
  std::vector<float> clip_speeds(static_cast<std::size_t>(nm)), scales(static_cast<std::size_t>(nm), 1.0f);
  float size = 0.1f, model_height = 0.1f;  // the characters' extent and height, scene units
  const float first_height = std::max(model.bounds_max.y - model.bounds_min.y, 1e-6f);
  for (int m = 0; m < nm; ++m) {
    const Model& mm = *models[m];
    clips[m] = mm.clips.empty() ? 0 : choose_clip(mm, s.clip);
    const float h = std::max(mm.bounds_max.y - mm.bounds_min.y, 1e-6f);
    FlowResult::Walk walk;
    walk.clip = mm.clips.empty() ? "" : mm.clips[clips[m]].name;
    if (s.clip_speed_mps > 0) {
      clip_speeds[m] = s.clip_speed_mps;
      walk.matched = "given";
    } else if (const float named = mm.clips.empty() ? 0.0f : speed_from_name(walk.clip); named > 0) {
      clip_speeds[m] = named;  // glTF's unit is the metre
      walk.matched = "name";
    } else if (const float measured = mm.baked_clips()[static_cast<std::size_t>(clips[m])].ground_speed; measured > 0) {
      clip_speeds[m] = measured;
      walk.matched = "measured";
    } else {
      walk.matched = "none";
    }
    walk.speed = clip_speeds[m];
    out.walks.push_back(walk);
    if (h > 2.0f * first_height || h < 0.5f * first_height) scales[m] = first_height / h;
    size = std::max(size, mm.radius * 2.0f * scales[m]);
    model_height = std::max(model_height, h * scales[m]);
  }
  int per_ring = std::max(4, static_cast<int>(std::ceil(std::sqrt(static_cast<float>(s.humans)))));
  int rings = (s.humans + per_ring - 1) / per_ring;
  std::vector<Walker> walkers;
  std::vector<std::pair<int, int>> slot;  // per human: (model, index in its crowd)
  float unit = model_height / 1.75f;  // scale the scene to the model: 1 "human metre"
  for (int i = 0; i < s.humans; ++i) {
    int ring = i % rings, k = i / rings;
    Walker w;
    w.radius = (2.0f + 1.6f * ring) * unit + 0.5f * size;
    w.speed = (0.6f + 1.2f * std::fmod(i * 0.6180339f, 1.0f)) * unit;
    w.dir = (ring % 2 == 0) ? 1 : -1;
    w.omega = w.dir * w.speed / w.radius;
    w.theta0 = 6.2831853f * (k + 0.37f * ring) / per_ring;
    walkers.push_back(w);
    const int m = i % nm;
    Character c;
    c.clip = clips[m];
    c.phase = 0.7f * i;
    c.scale = scales[m];
    // The clip's speed (in the model's units) scales with the character.
    c.speed = s.hold_poses ? 0.0f : clip_speeds[m] > 0 ? w.speed / (clip_speeds[m] * scales[m]) : 1.0f;
    slot.emplace_back(m, crowds[m].add(c));
  }
  float outer = walkers.empty() ? 2.0f : (2.0f + 1.6f * (rings - 1)) * unit + size;
  SceneCamera cam;
  cam.width = s.width;
  cam.height = s.height;
  cam.fov_y = 0.7854f;
  cam.target = {0, 0.45f * model_height, 0};
  float cam_dist = outer * 2.1f + model_height;
  float cam_height = outer * 0.9f + model_height;
  cam.near_plane = 0.05f * unit;
  cam.far_plane = cam_dist * 4;

  double g_ms = 0, i_ms = 0, refresh = 0, psnr_sum = 0, ssim_sum = 0, tri_g = 0, tri_s = 0, atlas_use = 0, cards = 0;
  double psnr_min = std::numeric_limits<double>::infinity(), psnr_ref_sum = 0;
  double deferred = 0, quad_texels = 0, drawn_texels = 0, short_lived = 0, ahead = 0, snapshot_frames = 0;
  int drawn_frames = 0;
  std::vector<double> g_times, i_times;  // per measured frame, ms
  int compared = 0, atlas_pages = 0;
  double class_se[3] = {0, 0, 0}, class_n[3] = {0, 0, 0};
  const int total = s.warmup + s.frames;
  for (int f = 0; f < total; ++f) {
    float t = f / s.fps;
    for (int i = 0; i < s.humans; ++i) {
      const Walker& w = walkers[i];
      float th = w.theta0 + w.omega * t;
      Character& c = crowds[slot[i].first][slot[i].second];
      c.position = {w.radius * std::cos(th), 0, w.radius * std::sin(th)};
      // Heading along the circle: d/dt of the position.
      glm::vec2 v(-std::sin(th) * w.dir, std::cos(th) * w.dir);
      c.yaw = std::atan2(v.x, v.y);
    }
    float orbit = glm::radians(s.orbit_deg_per_s) * t;
    cam.eye = {cam_dist * std::sin(orbit), cam_height, cam_dist * std::cos(orbit)};
    bool measured = f >= s.warmup;
    int mf = f - s.warmup;
    bool compare = measured && s.geometry && s.impostor && s.quality_every > 0 && mf % s.quality_every == 0;
    bool keep = measured && std::find(s.keep_frames.begin(), s.keep_frames.end(), mf) != s.keep_frames.end();
    const bool stream = measured && mf < s.on_frame_count && static_cast<bool>(s.on_frame);
    FlowFrameImages imgs;
    imgs.frame = mf;
    // One path: plan and draw every model's crowd into its target, timed until the GPU has
    // finished. Returns the plans' statistics summed over the models.
    std::vector<const FramePlan*> plans(static_cast<std::size_t>(nm));
    auto draw = [&](OffscreenTarget& target, RenderMode mode, double* ms) -> FrameStats {
      target.bind(true);
      gpu_finish();
      auto t0 = Clock::now();
      // Every model's crowd planned in one call on the threads (plan()'s plans).
      FramePlanner::plan_many(planner_ptrs, crowd_ptrs, cam, t, mode);
      for (int m = 0; m < nm; ++m) plans[m] = &planners[m]->plan_of_last_frame();
      auto t1 = Clock::now();
      // Every model's snapshots, then geometry, then the impostors in one back-to-front order across
      // the models (Renderer::draw_many: one draw with --atlas shared, layers of a draw per model
      // with per-model; with --gpu-stages model after model).
      Renderer::draw_many(renderer_ptrs, plans, draw_options);
      auto t2 = Clock::now();
      gpu_finish();
      auto t3 = Clock::now();
      *ms = std::chrono::duration<double, std::milli>(t3 - t0).count();
      if (measured) {
        FlowResult::Split& sp = mode == RenderMode::kGeometry ? out.geometry_split : out.impostor_split;
        sp.plan += std::chrono::duration<double, std::milli>(t1 - t0).count();
        sp.submit += std::chrono::duration<double, std::milli>(t2 - t1).count();
        sp.finish += std::chrono::duration<double, std::milli>(t3 - t2).count();
        StageTimes& acc = mode == RenderMode::kGeometry ? out.geometry_gpu : out.impostor_gpu;
        for (const auto& r : renderers) {
          const StageTimes g = r->stage_times();  // after the timed frame
          acc.snapshots += g.snapshots;
          acc.coverage += g.coverage;
          acc.geometry += g.geometry;
          acc.impostors += g.impostors;
          acc.valid = g.valid;
        }
      }
      FrameStats sum;
      int refreshed = 0, refreshable = 0;  // cards or whole impostors, as refresh_fraction counts
      float pixel_use = 0;
      for (std::size_t k = 0; k < plans.size(); ++k) {
        const FrameStats& st = plans[k]->stats;
        sum.geometry_triangles += st.geometry_triangles;
        sum.snapshot_triangles += st.snapshot_triangles;
        sum.deferred_refreshes += st.deferred_refreshes;
        sum.ahead_refreshes += st.ahead_refreshes;
        sum.snapshots += st.snapshots;
        sum.part_snapshots += st.part_snapshots;
        sum.part_cards += st.part_cards;
        sum.impostors += st.impostors;
        sum.quad_texels += st.quad_texels;
        sum.atlas_pages_used += st.atlas_pages_used;
        pixel_use += st.atlas_pixel_use;
        // A character drawn as geometry instead of a snapshot drawn once counts as refreshed.
        // (With part cards, as many cards as the model has parts.)
        const int per = s.part_cards ? static_cast<int>(models[k]->body_parts().size()) : 1;
        if (per > 1) {
          refreshed += st.part_snapshots + per * st.short_lived_geometry;
          refreshable += st.part_cards + per * st.short_lived_geometry;
        } else {
          refreshed += st.snapshots + st.short_lived_geometry;
          refreshable += st.impostors + st.short_lived_geometry;
        }
        sum.short_lived_geometry += st.short_lived_geometry;
        sum.characters += st.characters - st.culled;
      }
      sum.refresh_fraction = refreshable > 0 ? static_cast<float>(refreshed) / static_cast<float>(refreshable) : 0.0f;
      sum.atlas_pixel_use = pixel_use / static_cast<float>(nm);
      return sum;
    };
    double ms = 0;
    // The geometry path keeps nothing from frame to frame, so one warm-up frame readies it (its
    // shaders and buffers), or none (FlowSettings::geometry_warmup); the impostor path warms up over
    // every warm-up frame, as its cache fills and ages. A geometry frame of 10,000 humans takes
    // 1.4-2.9 s on llvmpipe.
    if (s.geometry && (measured || (f == 0 && s.geometry_warmup))) {
      const FrameStats st = draw(**target_g, RenderMode::kGeometry, &ms);
      if (measured) {
        g_ms += ms;
        g_times.push_back(ms);
        tri_g += static_cast<double>(st.geometry_triangles);
      }
      if (compare || keep || stream) imgs.geometry = (*target_g)->read_rgba();
    }
    if (s.impostor) {
      OffscreenTarget& ti = adaptive && last_short_lived > 0 ? *target_ims : **target_i;
      const FrameStats st = draw(ti, RenderMode::kImpostor, &ms);
      last_short_lived = st.short_lived_geometry;
      if (measured) {
        multisampled_frames += &ti == target_ims.get();
        i_ms += ms;
        i_times.push_back(ms);
        deferred += st.deferred_refreshes;
        ahead += st.ahead_refreshes;
        snapshot_frames += st.snapshots > 0 ? 1 : 0;  // with part cards: characters with a card refreshed
        // st.characters: the drawn ones (the models' characters not culled).
        short_lived += st.characters > 0 ? static_cast<double>(st.short_lived_geometry) / st.characters : 0.0;
        out.snapshots_max = std::max(out.snapshots_max, st.part_cards > 0 ? st.part_snapshots : st.snapshots);
        refresh += st.refresh_fraction;
        tri_s += static_cast<double>(st.snapshot_triangles);
        quad_texels += st.quad_texels;
        cards += st.part_cards;
        atlas_use += st.atlas_pixel_use;
        atlas_pages = std::max(atlas_pages, st.atlas_pages_used);
      }
      if (compare || keep || stream) imgs.impostor = ti.read_rgba();
      if (stream) imgs.refreshed = refreshed_boxes(plans, models, cam);
      if (compare) {  // after the timed frame: reads the fitted rectangles back
        for (int m = 0; m < nm; ++m) drawn_texels += renderers[m]->drawn_quad_texels(*plans[m]);
        ++drawn_frames;
      }
    }
    if (compare) {
      // Where the error is: interior, edges (partly covered), covered in one image only.
      const auto& ga = imgs.geometry;
      const auto& ia = imgs.impostor;
      for (size_t i = 0; i < static_cast<size_t>(s.width) * s.height; ++i) {
        const unsigned char* p = &ga[4 * i];
        const unsigned char* q = &ia[4 * i];
        if (p[3] == 0 && q[3] == 0) continue;
        double e = 0;
        for (int k = 0; k < 3; ++k) {
          double d = double(p[k]) - double(q[k]);  // premultiplied, as psnr_covered
          e += d * d;
        }
        int c = (p[3] == 255 && q[3] == 255) ? 0 : (p[3] == 0 || q[3] == 0) ? 2 : 1;
        class_se[c] += e;
        class_n[c] += 1;
      }
    }
    if (compare) {
      const PsnrPair both = psnr_both(imgs.geometry.data(), imgs.impostor.data(), s.width, s.height);
      double p = both.covered, r = both.reference;
      double q = ssim_covered(imgs.geometry.data(), imgs.impostor.data(), s.width, s.height);
      if (std::isinf(p)) p = 99.0;
      if (std::isinf(r)) r = 99.0;
      psnr_sum += p;
      psnr_ref_sum += r;
      ssim_sum += q;
      psnr_min = std::min(psnr_min, p);
      ++compared;
    }
    if (stream) s.on_frame(imgs);
    if (keep) out.images.push_back(std::move(imgs));
  }
  int n = std::max(1, s.frames);
  out.geometry_ms = s.geometry ? g_ms / n : 0;
  out.impostor_ms = s.impostor ? i_ms / n : 0;
  out.ratio = (s.geometry && s.impostor && g_ms > 0) ? i_ms / g_ms : 0;
  out.refresh_fraction = s.impostor ? refresh / n : 0;
  out.impostor_multisampled_frames = s.impostor ? static_cast<double>(multisampled_frames) / n : 0;
  out.psnr_db = compared ? psnr_sum / compared : 0;
  out.psnr_min_db = compared ? psnr_min : 0;
  out.psnr_ref_db = compared ? psnr_ref_sum / compared : 0;
  out.ssim = compared ? ssim_sum / compared : 0;
  const double se_all = class_se[0] + class_se[1] + class_se[2];
  FlowResult::ErrorClass* classes[3] = {&out.interior, &out.edge, &out.one_only};
  for (int c = 0; c < 3; ++c) {
    classes[c]->mse = class_n[c] > 0 ? class_se[c] / (3.0 * class_n[c]) : 0.0;
    classes[c]->pixels = compared ? class_n[c] / compared : 0.0;
    classes[c]->share = se_all > 0 ? class_se[c] / se_all : 0.0;
  }
  out.geometry_triangles = tri_g / n;
  out.snapshot_triangles = tri_s / n;
  out.part_cards = cards / n;
  out.deferred_refreshes = deferred / n;
  out.ahead_refreshes = ahead / n;
  out.snapshot_frames = snapshot_frames / n;
  out.short_lived_geometry = short_lived / n;
  out.quad_texels = quad_texels / n;
  out.drawn_quad_texels = drawn_frames ? drawn_texels / drawn_frames : 0.0;
  for (FlowResult::Split* sp : {&out.geometry_split, &out.impostor_split}) {
    sp->plan /= n;
    sp->submit /= n;
    sp->finish /= n;
  }
  for (StageTimes* g : {&out.geometry_gpu, &out.impostor_gpu}) {
    g->snapshots /= n;
    g->coverage /= n;
    g->geometry /= n;
    g->impostors /= n;
  }
  out.geometry_spread = spread(g_times);
  out.impostor_spread = spread(i_times);
  out.atlas_pixel_use = atlas_use / n;
  out.atlas_pages = atlas_pages;
  return out;
}

}  // namespace bb::cli
