// bodybuilder render FILE.glb -o OUT.png [--mode geometry|impostor] [--time S] [--azimuth DEG]
//   [--elevation DEG] [--distance M] [--size WxH] [--clip NAME] [--snapshot perspective|ortho]
//   [--frames N [--fps F] [--spin DEG_PER_S]] [--json]
// One character, headless (EGL), RGBA PNG with a transparent background. In impostor mode the
// snapshot is taken at the given time and view, into a window of the character's on-screen size,
// and drawn as a camera-facing plane. With --frames N > 1, an animated PNG of N such pictures, the
// clip played on from --time at F frames per second and the camera turned by --spin.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "bb/runtime/headless.h"
#include "bb/runtime/model.h"
#include "bb/runtime/portrait.h"
#include "animated_png.h"
#include "commands.h"
#include "io.h"
#include "model_notes.h"

namespace bb::cli {

namespace {

struct RenderArgs {
  std::string input, output, mode = "geometry", size = "512x512", clip, snapshot = "perspective";
  float time = 0.0f, azimuth = 0.0f, elevation = 10.0f, distance = 0.0f;
  int lod = -1;  // -1: chosen by screen size
  int lods = 3;  // LoadOptions::lod_levels
  int frames = 1;          // > 1: an animated PNG
  float fps = 30.0f;       // its frames per second of clip time
  float spin = 0.0f;       // degrees of azimuth per second
  bool json = false;
};

int run_render(const RenderArgs& a) {
  using clock = std::chrono::steady_clock;
  auto ms = [](clock::time_point t0) { return std::chrono::duration<double, std::milli>(clock::now() - t0).count(); };
  runtime::PortraitOptions o;
  if (a.mode == "geometry") o.mode = runtime::RenderMode::kGeometry;
  else if (a.mode == "impostor") o.mode = runtime::RenderMode::kImpostor;
  else {
    std::cerr << "bodybuilder render: --mode must be geometry or impostor, not \"" << a.mode << "\"\n";
    return 2;
  }
  if (a.snapshot != "perspective" && a.snapshot != "ortho") {
    std::cerr << "bodybuilder render: --snapshot must be perspective or ortho\n";
    return 2;
  }
  o.orthographic = a.snapshot == "ortho";
  if (!parse_size(a.size, 8, 8192, &o.width, &o.height)) {
    std::cerr << "bodybuilder render: --size must be WxH between 8 and 8192, not \"" << a.size << "\"\n";
    return 2;
  }
  if (auto st = check_output_file(a.output); !st) {
    std::cerr << "bodybuilder render: " << st.error().message() << "\n";
    return 1;
  }
  o.time = a.time;
  o.azimuth_deg = a.azimuth;
  o.elevation_deg = a.elevation;
  o.distance = a.distance;
  auto t0 = clock::now();
  runtime::LoadOptions load;
  load.lod_levels = a.lods;
  auto model = runtime::load_model(a.input, load);
  if (!model) {
    std::cerr << "bodybuilder render: " << model.error().message() << "\n";
    return 1;
  }
  const double load_ms = ms(t0);
  for (const std::string& n : model_notes(*model)) std::cerr << "bodybuilder render: note: " << n << "\n";
  if (a.lod >= 0) {
    if (a.lod >= static_cast<int>(model->lods.size())) {
      std::cerr << "bodybuilder render: " << a.input << ": --lod " << a.lod << ": the model has "
                << model->lods.size() << " level" << (model->lods.size() == 1 ? "" : "s") << " (see --lods)\n";
      return 1;
    }
    model->lods = {model->lods[a.lod]};  // that level at every size
  }
  if (!a.clip.empty()) {
    o.clip = model->find_clip(a.clip);
    if (o.clip < 0) {
      std::cerr << "bodybuilder render: " << a.input << ": no clip named \"" << a.clip << "\"\n";
      return 1;
    }
  }
  t0 = clock::now();
  auto ctx = runtime::HeadlessContext::create();
  if (!ctx) {
    std::cerr << "bodybuilder render: " << ctx.error().message() << "\n";
    return 3;
  }
  const double ctx_ms = ms(t0);
  t0 = clock::now();
  // One renderer for every frame of an animation (its programs and target made once).
  runtime::PortraitRenderer portraits(*model);
  auto img = portraits.render(o);
  if (!img) {
    std::cerr << "bodybuilder render: " << img.error().message() << "\n";
    return 3;
  }
  if (a.frames > 1) {
    // Frame k: the clip at time + k / fps, the camera turned by spin * k / fps.
    AnimatedPng apng(img->width, img->height, 4, 100, static_cast<std::uint16_t>(std::lround(100.0 * a.fps)));
    for (int k = 0; k < a.frames; ++k) {
      if (k > 0) {
        runtime::PortraitOptions ok = o;
        ok.time = a.time + static_cast<float>(k) / a.fps;
        ok.azimuth_deg = a.azimuth + a.spin * static_cast<float>(k) / a.fps;
        img = portraits.render(ok);
        if (!img) {
          std::cerr << "bodybuilder render: frame " << k << ": " << img.error().message() << "\n";
          return 3;
        }
      }
      if (auto st = apng.add(img->rgba.data()); !st) {
        std::cerr << "bodybuilder render: " << a.output << ": " << st.error().message() << "\n";
        return 1;
      }
    }
    if (auto st = apng.write(a.output); !st) {
      std::cerr << "bodybuilder render: " << st.error().message() << "\n";
      return 1;
    }
  }
  const double render_ms = ms(t0) / a.frames;
  if (a.frames == 1)
    if (auto s = write_png(a.output, img->width, img->height, img->rgba.data()); !s) {
      std::cerr << "bodybuilder render: " << s.error().message() << "\n";
      return 1;
    }
  long covered = 0;
  for (std::size_t i = 3; i < img->rgba.size(); i += 4) covered += img->rgba[i] > 0;
  if (a.json) {
    nlohmann::json j = {{"file", a.input},       {"output", a.output},          {"mode", a.mode},
                        {"width", img->width},   {"height", img->height},       {"time_s", a.time},
                        {"clip", o.clip},        {"covered_pixels", covered},   {"window_px", img->window_pixels},
                        {"load_ms", load_ms},    {"context_ms", ctx_ms},        {"render_ms", render_ms},
                        {"snapshot", a.snapshot}, {"gl", (*ctx)->description()}, {"frames", a.frames}};
    if (a.frames > 1) {
      j["fps"] = a.fps;
      j["spin_deg_per_s"] = a.spin;
    }
    std::cout << json_text(j) << "\n";
  } else {
    if (a.frames > 1)
      std::printf("wrote %s (%d frames at %g per second, %dx%d, %s; load %.1f ms, render %.1f ms a frame on %s)\n",
                  a.output.c_str(), a.frames, static_cast<double>(a.fps), img->width, img->height, a.mode.c_str(), load_ms,
                  render_ms, (*ctx)->description().c_str());
    else
      std::printf("wrote %s (%dx%d, %s, %ld covered pixels; load %.1f ms, render %.1f ms on %s)\n", a.output.c_str(),
                  img->width, img->height, a.mode.c_str(), covered, load_ms, render_ms, (*ctx)->description().c_str());
  }
  return 0;
}

void add_render_command(CLI::App& app, int* status) {
  auto* cmd = app.add_subcommand("render", "Render one skinned glTF character to an RGBA PNG (headless, EGL)");
  auto a = std::make_shared<RenderArgs>();
  cmd->add_option("file", a->input, "Skinned .glb or .gltf")->required();
  cmd->add_option("-o,--output", a->output, "PNG to write")->required();
  cmd->add_option("--mode", a->mode, "geometry or impostor")->capture_default_str();
  // The ranges keep the values what a float holds to a useful precision (a clip time of 1e5 s still
  // steps by 8 ms; 1e40 was no float at all).
  cmd->add_option("--time", a->time, "Seconds into the clip (looped), -100000 to 100000")
      ->capture_default_str()
      ->check(finite_number(-1e5, 1e5));
  cmd->add_option("--azimuth", a->azimuth, "Degrees around the character; 0 = in front (+Z)")
      ->capture_default_str()
      ->check(finite_number(-36000.0, 36000.0));
  cmd->add_option("--elevation", a->elevation, "Degrees above the horizon")
      ->capture_default_str()
      ->check(finite_number(-36000.0, 36000.0));
  cmd->add_option("--distance", a->distance, "Metres from the character's centre Ta; 0 = fit")
      ->capture_default_str()
      ->check(finite_number(0.0, 1e6));
  cmd->add_option("--size", a->size, "Image size WxH in pixels")->capture_default_str();
  cmd->add_option("--clip", a->clip, "Clip name (default: the first)");
  cmd->add_option("--lod", a->lod, "Draw this level of detail (default: chosen by screen size)")->check(whole_number(0, 1000));
  cmd->add_option("--lods", a->lods,
                  "A file with one level: up to N coarser levels made at load, each used where its error shows as "
                  "under a pixel of a 1080-pixel-high view (0: none)")
      ->capture_default_str()
      ->check(whole_number(0, 8));
  cmd->add_option("--snapshot", a->snapshot, "Impostor snapshot projection: perspective (from the eye) or ortho (the paper's)")
      ->capture_default_str();
  cmd->add_option("--frames", a->frames,
                  "N > 1: an animated PNG of N frames (browsers play it), the clip played on from --time")
      ->capture_default_str()
      ->check(whole_number(1, 1000));
  cmd->add_option("--fps", a->fps, "With --frames: frames per second of clip time")
      ->capture_default_str()
      ->check(finite_number(1.0, 120.0));
  cmd->add_option("--spin", a->spin, "With --frames: the camera turns around the character, degrees per second")
      ->capture_default_str()
      ->check(finite_number(-36000.0, 36000.0));
  cmd->add_flag("--json", a->json, "Print one JSON object with the figures (covered_pixels: the last frame's)");
  cmd->callback([=] { *status = run_render(*a); });
}

const Registrar registrar(35, add_render_command);

}  // namespace
}  // namespace bb::cli
