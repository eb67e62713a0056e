// A game's use of the installed runtime (tests/runtime/package): the lifecycle bb/runtime.h gives, into
// offscreen targets of a headless context. Draws 12 walkers of MODEL.glb for 30 frames as
// impostors and the same frames as geometry, and checks what a game would see: every character an
// impostor, a snapshot for each in the first frame and far fewer after (the cache), and impostor
// frames covering the pixels the geometry frames cover. The same walkers as two models' crowds (the
// file loaded twice, alternate walkers each) sharing one atlas, planned with plan_many and drawn with
// draw_many, must cover the pixels the one model's impostor frames cover. Exit status 0 when all hold.
// GAME_DUMP=PREFIX writes the last frames as PREFIXimpostors.ppm and PREFIXgeometry.ppm.
#include <bb/runtime.h>
#include <bb/runtime/headless.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

namespace rt = bb::runtime;

namespace {

constexpr int kWidth = 320, kHeight = 240, kFrames = 30, kHumans = 12;

// Pixels (alpha over one half) covered in both images over those covered in either.
double overlap(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b, long& either) {
  long both = 0;
  either = 0;
  for (std::size_t i = 3; i < a.size(); i += 4) {
    both += a[i] > 127 && b[i] > 127;
    either += a[i] > 127 || b[i] > 127;
  }
  return either > 0 ? static_cast<double>(both) / static_cast<double>(either) : 0.0;
}

void dump(const std::string& path, const std::vector<std::uint8_t>& rgba) {
  if (std::FILE* f = std::fopen(path.c_str(), "wb")) {
    std::fprintf(f, "P6 %d %d 255\n", kWidth, kHeight);
    for (std::size_t i = 0; i < rgba.size(); i += 4) std::fwrite(&rgba[i], 1, 3, f);
    std::fclose(f);
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: game MODEL.glb\n");
    return 2;
  }
  auto context = rt::HeadlessContext::create();
  if (!context) {
    std::fprintf(stderr, "%s\n", context.error().message().c_str());
    return 1;
  }
  auto model = rt::load_model(argv[1]);
  if (!model) {
    std::fprintf(stderr, "%s\n", model.error().message().c_str());
    return 1;
  }
  // The test bed's measured choices for this scene (single-sampled offscreen targets): the installed
  // tuning header, as a game starts from it.
  rt::ImpostorConfig config;
  config.texels_per_pixel = 1.0f;
  config = rt::tuned_config(config, {.samples = 1, .software = rt::software_rasterizer()});
  rt::Crowd crowd(*model);
  for (int i = 0; i < kHumans; ++i)
    crowd.add({.position = {1.5f * static_cast<float>(i % 4) - 2.25f, 0, -1.5f * static_cast<float>(i / 4)},
               .yaw = 0.5f * static_cast<float>(i),
               .clip = 0,
               .phase = 0.37f * static_cast<float>(i),
               .speed = 1.0f});
  rt::FramePlanner impostor_planner(*model, config), geometry_planner(*model, config);
  auto renderer = rt::Renderer::create(*model, config);
  if (!renderer) {
    std::fprintf(stderr, "%s\n", renderer.error().message().c_str());
    return 1;
  }
  // Two models sharing one atlas: walker i of model i % 2.
  auto other = rt::load_model(argv[1]);
  if (!other) {
    std::fprintf(stderr, "%s\n", other.error().message().c_str());
    return 1;
  }
  const rt::Model* kinds[2] = {&*model, &*other};
  std::vector<rt::Crowd> crowds = {rt::Crowd(*kinds[0]), rt::Crowd(*kinds[1])};
  for (int i = 0; i < kHumans; ++i) crowds[static_cast<std::size_t>(i % 2)].add(crowd[static_cast<std::size_t>(i)]);
  std::vector<std::unique_ptr<rt::FramePlanner>> planners;
  std::vector<std::unique_ptr<rt::Renderer>> renderers;
  for (int k = 0; k < 2; ++k) {
    const rt::ImpostorConfig cfg = rt::shared_atlas_config(config, k, 2);
    planners.push_back(std::make_unique<rt::FramePlanner>(*kinds[k], cfg));
    auto r = rt::Renderer::create(*kinds[k], cfg, k > 0 ? renderers.front().get() : nullptr);
    if (!r) {
      std::fprintf(stderr, "%s\n", r.error().message().c_str());
      return 1;
    }
    renderers.push_back(std::move(*r));
  }
  rt::FramePlanner* planner_ptrs[2] = {planners[0].get(), planners[1].get()};
  const rt::Crowd* crowd_ptrs[2] = {&crowds[0], &crowds[1]};
  rt::Renderer* renderer_ptrs[2] = {renderers[0].get(), renderers[1].get()};
  auto impostors = rt::OffscreenTarget::create(kWidth, kHeight);
  auto geometry = rt::OffscreenTarget::create(kWidth, kHeight);
  auto two = rt::OffscreenTarget::create(kWidth, kHeight);
  if (!impostors || !geometry || !two) {
    std::fprintf(stderr, "no offscreen target\n");
    return 1;
  }
  const rt::SceneCamera cam{.eye = {0, 3, 9}, .target = {0, 0.9f, -1.5f}, .width = kWidth, .height = kHeight};
  int first_snapshots = -1, later_snapshots = 0, later_impostors = 0;
  long first_either = 0, last_either = 0;
  double first_overlap = 0.0, last_overlap = 0.0;
  for (int f = 0; f < kFrames; ++f) {
    const float seconds = static_cast<float>(f) / 30.0f;
    (*impostors)->bind(true);
    const rt::FramePlan& plan = impostor_planner.plan(crowd, cam, seconds, rt::RenderMode::kImpostor);
    (*renderer)->draw(plan);
    (*geometry)->bind(true);
    (*renderer)->draw(geometry_planner.plan(crowd, cam, seconds, rt::RenderMode::kGeometry));
    (*two)->bind(true);
    rt::FramePlanner::plan_many(planner_ptrs, crowd_ptrs, cam, seconds, rt::RenderMode::kImpostor);
    const rt::FramePlan* plans[2] = {&planners[0]->plan_of_last_frame(), &planners[1]->plan_of_last_frame()};
    rt::Renderer::draw_many(renderer_ptrs, plans);
    if (f == 0) {
      first_snapshots = plan.stats.snapshots;
      first_overlap = overlap((*impostors)->read_rgba(), (*geometry)->read_rgba(), first_either);
    } else {
      later_snapshots += plan.stats.snapshots;
      later_impostors += plan.stats.impostors;
    }
  }
  const std::vector<std::uint8_t> a = (*impostors)->read_rgba(), b = (*geometry)->read_rgba();
  last_overlap = overlap(a, b, last_either);
  long two_either = 0;
  const double two_overlap = overlap(a, (*two)->read_rgba(), two_either);
  if (const char* prefix = std::getenv("GAME_DUMP")) {
    dump(std::string(prefix) + "impostors.ppm", a);
    dump(std::string(prefix) + "geometry.ppm", b);
  }
  std::printf("%s\nfirst frame: %d snapshots for %d characters, %ld pixels covered by either path, %.3f of them "
              "by both; then %d snapshots for %d impostors drawn; last frame: %ld pixels, %.3f by both; two models "
              "in one atlas against one: %ld pixels, %.3f by both\n",
              context.value()->description().c_str(), first_snapshots, kHumans, first_either, first_overlap,
              later_snapshots, later_impostors, last_either, last_overlap, two_either, two_overlap);
  const bool ok = first_snapshots == kHumans && later_impostors == kHumans * (kFrames - 1) &&
                  later_snapshots < later_impostors / 4 && first_either > 2000 && first_overlap > 0.9 &&
                  last_overlap > 0.5 && two_either > 2000 && two_overlap > 0.98;
  std::printf("%s\n", ok ? "ok" : "FAILED");
  return ok ? 0 : 1;
}
