// The paper's human flow test bed (section 6), used by `bodybuilder flow` and `bodybuilder demo`.
//
// N humans walk on concentric circles at different constant speeds, all in view of a camera
// that may orbit. Each frame is planned and drawn by the geometry path and by the impostor path
// (same scene time, interleaved in one run); a frame's time is the CPU planning plus the GPU work
// to completion (glFinish), so both paths are measured alike. Impostor frames are compared with
// the geometry frame of the same instant (PSNR over covered pixels, SSIM).
// The geometry path draws into a target with `msaa` samples; the impostor path into a single-sampled
// one when its edges blend (runtime::impostor_target_samples: the same frames), else the same.
#pragma once

#include <functional>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "bb/runtime/crowd.h"
#include "bb/runtime/model.h"
#include "bb/runtime/renderer.h"
#include "bb/runtime/tuning.h"
#include "bb/result.h"
#include <nlohmann/json.hpp>

namespace bb::cli {

// One measured frame's pictures, as each path drew it (premultiplied: the background is clear).
struct FlowFrameImages {
  int frame = 0;
  std::vector<unsigned char> geometry, impostor;  // RGBA8, rows top to bottom
  // Only for FlowSettings::on_frame: where the impostors (with part cards: the cards) refreshed in
  // this impostor frame lie on screen, each the box of its snapshot's planned quad, pixels from
  // the top left (x0, y0, x1, y1).
  std::vector<glm::vec4> refreshed;
};

inline constexpr int kDefaultWarmup = 30;  // FlowSettings::warmup, `flow --warmup`

struct FlowSettings {
  int humans = 20;
  int frames = 120;            // measured frames (after `warmup` frames)
  // Frames before the measured ones. The impostor path draws them all (its cache fills, and its
  // snapshots' ages spread out as they do in a long run), the geometry path the first alone (its
  // shaders and buffers), so they cost little. Every snapshot is fresh in the first frame and they
  // age in step; with 3 warm-up frames a short run saw too few of their refreshes: the default crowd
  // at 8 degrees (posture test off) 16.6x with a refresh fraction of 0.0375 in 20 frames against
  // 13.1x and 0.055 after 30, and part cards' PSNR 0.2 dB high (forty-eighth session).
  int warmup = kDefaultWarmup;
  // Whether the geometry path draws the first warm-up frame. `--scaling` does without: after the
  // first crowd size the first frame of 10,000 humans costs what the next ones do (2,537.5 against
  // 2,539.5 ms a frame in two runs of 20 and 10,000 humans), and it took 2-3 s twice over.
  bool geometry_warmup = true;
  int width = 1280, height = 1024;
  float fps = 30.0f;           // scene time step 1/fps per frame
  bool geometry = true, impostor = true;
  bool posture_test = true;
  float posture_threshold = 0.4f;
  bool view_test = true;
  float view_deg = 8.0f;
  bool distance_weighting = false;
  float screen_weighting_px = 32.0f;  // CacheConfig::reference_pixels (0: off)
  float orbit_deg_per_s = 0.0f;  // camera orbit speed
  int quality_every = 4;         // compare images every k-th measured frame
  int msaa = 4;                  // samples per pixel of the scene window (the geometry path's target)
  // Samples of the impostor path's target: 0 auto (runtime::impostor_target_samples, 1 where the
  // impostors' edges need no samples: the same frames, less to write; on a GPU adaptive), -1
  // adaptive (that, and the scene's samples for a frame after one that drew a short-lived
  // character as geometry), else this many.
  int impostor_target_samples = 0;
  // Impostor windows chosen for this many texels per pixel, and how impostor edges meet the
  // scene. The test bed's defaults are the fastest setting that keeps edges antialiased: 1 texel
  // per pixel and sorted blending, which the runtime rasterizes single-sampled (on llvmpipe, 20
  // humans: 27.0 dB at threshold 0 against 24.7 with alpha to coverage, and 3-10 % faster at 8
  // and 17 degrees). The runtime's own default of 2 texels per pixel gives ~31 dB fresh but
  // draws 4x the texels.
  float texels_per_pixel = 1.0f;
  // Switches that isolate what limits image quality:
  std::string impostor_edges = "blend";     // blend (sorted), samples, coverage (alpha to coverage), test
  bool snapshot_lod_from_screen = true;     // false: the LOD that matches the window (section 4.3)
  bool perspective_snapshots = true;        // false: the paper's orthographic snapshot camera
  bool hold_poses = false;                  // every human keeps one pose (no pose lag)
  bool part_cards = false;                  // ImpostorConfig::part_cards (one card per body part)
  int refresh_budget = 0;                   // CacheConfig::refresh_budget (0: no limit)
  float refresh_ahead = 0.0f;               // CacheConfig::ahead_fraction (0: off)
  int ahead_count = 4;                      // CacheConfig::ahead_count
  bool turn_limb_cards = false;             // ImpostorConfig::turn_limb_cards
  bool parallax_cards = false;              // ImpostorConfig::parallax_cards (depth-corrected cards)
  bool relight = false;                     // ImpostorConfig::relight (impostors lit as drawn)
  bool parallax_depth_pass = false;         // ImpostorConfig::parallax_depth_pass
  bool lead_cards = true;                   // ImpostorConfig::lead_cards
  float view_lead = 0.0f;                   // ImpostorConfig::view_lead (0: off)
  // ImpostorConfig::aligned_snapshots (texels on pixels); -1: auto (runtime::tuned_aligned_snapshots,
  // decided once the rasterizer is known).
  int aligned_snapshots = 0;
  bool exact_scale = false;                 // ImpostorConfig::texel_per_pixel (the asked texels per pixel, not the window's)
  int snapshot_samples = 1;                 // ImpostorConfig::snapshot_samples
  int impostor_taps = 4;                    // ImpostorConfig::impostor_taps (0: auto, tuned_impostor_taps)
  // ImpostorConfig::aligned_phase always follows the grid and the taps (runtime::tuned_aligned_phase).
  bool fit_quads = true;                    // ImpostorConfig::fit_quads_to_coverage
  // ImpostorConfig::fit_quads_from_vertices (--quad-fit vertices); -1: auto (on a software rasterizer
  // but for depth-corrected cards, where it is the faster; the coverage pass on a GPU)
  int fit_from_vertices = -1;
  bool shared_atlas = true;                 // one atlas for every model (shared_atlas_config) where the GL
                                            // makes one texture that big, else one each
  int coverage_group = 0;                   // ImpostorConfig::coverage_group (0: by the rasterizer)
  int quad_fetch = 0;                       // ImpostorConfig::quad_fetch (0: by the rasterizer, 1 instanced, 2 pulled)
  bool time_stages = false;                 // GPU timestamps between the renderer's stages (gpu_ms_stages)
  int flush_every_indices = -1;             // DrawOptions::flush_every_indices (-1: auto, 0: never)
  // ImpostorConfig::short_lived_as_geometry: -1 auto (on where the impostor target has the
  // scene's samples, on a GPU or where msaa is 1: a character drawn as geometry there is the
  // geometry's picture, and a snapshot costs what drawing the character does or more), 0 off
  // (every refresh a snapshot), 1 on.
  int short_lived = -1;
  unsigned planner_threads = 0;             // ImpostorConfig::planner_threads (0: every hardware thread)
  runtime::WindowSizes windows;             // ImpostorConfig::windows (the runtime's default: 256 to 8)
  std::string clip;              // the clip every model walks; empty: the first named like "walk", else the first that walks, else 0
  // Speed the clip walks at, model units per second; 0: from the clip name "..._1.20mps" (metres,
  // glTF's unit), else measured (BakedClip::ground_speed), else none (played at its own rate).
  float clip_speed_mps = 0;
  std::vector<int> keep_frames;  // measured frame indices whose images are returned
  // Called with both paths' pictures of the first `on_frame_count` measured frames, in order, each
  // read back after the frame's timing (`bodybuilder flow --animation`); empty: none.
  std::function<void(const FlowFrameImages&)> on_frame;
  int on_frame_count = 0;
};

struct FlowResult {
  int humans = 0, frames = 0, width = 0, height = 0;
  // Samples per pixel of each path's target as the driver gave them (llvmpipe: 1 or 4, whatever
  // --msaa asked).
  int geometry_target_samples = 0, impostor_target_samples = 0;
  // --impostor-target adaptive (auto on a GPU): the impostor frames that followed one with a
  // short-lived character drawn as geometry took a target of the scene's samples; their share.
  bool impostor_target_adaptive = false;
  double impostor_multisampled_frames = 0;
  double geometry_ms = 0, impostor_ms = 0;  // mean per frame
  // Spread of the per-frame times over the measured frames: median, 95th percentile, worst, and
  // standard deviation (ms). What a crowd-level refresh budget (CacheConfig::refresh_budget)
  // flattens; the median is what a few slow frames (a busy machine) leave as it was.
  struct Spread {
    double median = 0, p95 = 0, max = 0, sd = 0;
  } geometry_spread, impostor_spread;
  // Where a path's frame time goes, mean ms per frame: the planner (CPU), the renderer's
  // submission (CPU, GL calls until Renderer::draw returns) and the wait for the GPU to finish
  // (glFinish). They add up to geometry_ms / impostor_ms.
  struct Split {
    double plan = 0, submit = 0, finish = 0;
  } geometry_split, impostor_split;
  // GPU time of the renderer's stages (Renderer::stage_times), mean ms per frame over the
  // measured frames of each path (geometry: its geometry stage; impostors: the other three).
  runtime::StageTimes geometry_gpu, impostor_gpu;
  double deferred_refreshes = 0;            // mean stale impostors held back per frame by the budget
  double ahead_refreshes = 0;               // mean impostors refreshed ahead per frame (CacheConfig::ahead_fraction)
  // Share of the measured impostor frames that took a snapshot (and so paid for a snapshot pass).
  double snapshot_frames = 0;
  bool short_lived_as_geometry = false;     // what FlowSettings::short_lived resolved to
  int coverage_group = 4;                   // what FlowSettings::coverage_group resolved to
  bool pulled_quads = false;                // what FlowSettings::quad_fetch resolved to
  bool fit_from_vertices = false;           // what FlowSettings::fit_from_vertices resolved to
  bool aligned_snapshots = false;           // what FlowSettings::aligned_snapshots resolved to
  int impostor_taps = 4;                    // what FlowSettings::impostor_taps resolved to
  float aligned_phase = 0.0f;               // ImpostorConfig::aligned_phase (pixels) as drawn
  bool shared_atlas = false;                // the models share one atlas (FlowSettings::shared_atlas, if it fits)
  // Mean share of the drawn characters that the impostor path drew as geometry instead of a
  // snapshot drawn once (ImpostorConfig::short_lived_as_geometry).
  double short_lived_geometry = 0;
  int snapshots_max = 0;                    // most impostors (part cards: cards) refreshed in one measured frame
  double ratio = 0;                         // impostor / geometry
  double refresh_fraction = 0;              // mean snapshots / impostors
  double psnr_db = 0, ssim = 0;             // means over compared frames
  double psnr_min_db = 0;
  // Mean over compared frames of psnr_reference: the squared error of every pixel covered in
  // either image over the pixels the geometry frame covers, which an impostor's faint halo cannot
  // raise as it can psnr_db (whose mean takes the halo's pixels in).
  double psnr_ref_db = 0;
  // Where the squared error comes from, over the compared frames (premultiplied RGB as in
  // psnr_db): pixels covered in both images, pixels partly covered in at least one (edges), and
  // pixels covered in one image only. mse per channel, pixels per frame.
  struct ErrorClass {
    double mse = 0, pixels = 0, share = 0;
  } interior, edge, one_only;
  double geometry_triangles = 0, snapshot_triangles = 0;  // mean per frame
  double quad_texels = 0;  // mean per frame: window texels under the impostor quads (their fill)
  double drawn_quad_texels = 0;  // the same as drawn (fitted to the coverage), mean over compared frames
  double atlas_pixel_use = 0;
  int atlas_pages = 0;
  std::string device;
  // With part cards: the name of each body part's bone (the model's automatic decomposition).
  std::vector<std::string> parts;
  double part_cards = 0;  // mean cards drawn per impostor frame
  // Per model: the clip its humans walk, the speed it walks at (model units per second, 0: none)
  // and where that came from ("name", "measured", "given" or "none": played at its own rate).
  struct Walk {
    std::string clip;
    double speed = 0;
    std::string matched;
  };
  std::vector<Walk> walks;
  std::vector<FlowFrameImages> images;
};

// Below this many triangles a body part (part_triangles), `flow --impostor-parts` and `inspect` note that
// part cards gain little over geometry, and below this many a character (runtime::kFewTriangles) `flow`
// notes the same of whole impostors: a card (its quad and its refreshes) costs about what drawing a few
// dozen triangles does (flow test bed, 8 degrees, posture off: SimpleSkin, 4 a part, 0.68x geometry's
// speed; the Fox, 36, 1.6x; RiggedSimple, 94, 2.8x; CesiumMan, 292, 6.5x; whole impostors 1.0x / 7.5x /
// 4.7x / 19x).
constexpr std::size_t kFewTrianglesPerPart = runtime::kFewTriangles;

// Triangles a body part on average: the finest level's over Model::body_parts, rounded; 0 for a model
// of one part (whole impostors only) or no level.
std::size_t part_triangles(const runtime::Model& m);

// FlowSettings::impostor_edges ("blend", "coverage", "samples", "test" or "centre") as the renderer's mode.
runtime::ImpostorEdges edges_of(const std::string& impostor_edges);

// Runs the test bed on `model` (must have a current GL context). `device` names the GL renderer.
Result<FlowResult> run_flow(const runtime::Model& model, const FlowSettings& settings, const std::string& device);
// The same with a crowd of several models: human i is of models[i % models.size()] (each model
// with its own renderer and atlas, drawn into the same frame); the scene is scaled to the largest.
// The figures are the crowd's (refresh_fraction: refreshed over drawn impostors or cards, summed).
Result<FlowResult> run_flow(std::span<const runtime::Model* const> models, const FlowSettings& settings,
                            const std::string& device);

// What `bodybuilder flow` was asked (the CLI's flags).
struct FlowArgs {
  // --model, repeatable (a crowd of several models); none: the built-in body and `variants`
  // seeded variants of it (-1: the default, kDefaultVariants).
  std::vector<std::string> models;
  int variants = -1;
  std::string out = "out/flow", size = "1280x1024", mode = "both", posture = "0.4", view = "8", sweep;
  std::string sweep_thresholds;  // --sweep-thresholds: empty, the paper's range
  int humans = 20, frames = 120, warmup = kDefaultWarmup;
  bool json = false, scaling = false, distance_weighting = false;
  bool targets = false;  // --targets: also the worst case and 5, 8, 17 degrees with these settings
  std::string screen_weighting = "32";
  float orbit = 0;
  int msaa = 4;
  std::string impostor_target = "auto";  // auto or scene (the impostor path's target has --msaa samples)
  float texels_per_pixel = 1.0f;  // see FlowSettings
  std::string impostor_edges = "auto", snapshot_lod = "screen", snapshot_camera = "perspective";
  bool hold_poses = false;
  std::string clip;  // --clip: every model's clip by name (empty: its walk)
  int lods = 3;      // --lods: LoadOptions::lod_levels for every model
  bool impostor_parts = false;
  int refresh_budget = 0;
  std::string refresh_ahead = "off";  // --refresh-ahead: a fraction in (0, 1) or off
  int ahead_count = 4;
  std::string limb_cards = "fixed";
  std::string card_depth = "off";
  std::string relight = "off";
  std::string card_lead = "on";
  std::string view_lead = "off";  // --view-lead: a fraction of the view threshold in (0, 1], or off
  std::string snapshot_grid = "auto";
  std::string snapshot_scale = "auto";
  int snapshot_samples = 1;
  std::string impostor_taps = "auto";
  std::string quad_fit = "auto";
  std::string atlas = "shared";
  std::string coverage_group = "auto";
  std::string quad_fetch = "auto";
  bool gpu_stages = false;
  std::string flush_every = "auto";
  std::string short_lived = "auto";  // auto, geometry or snapshot (FlowSettings::short_lived)
  int planner_threads = 0;
  bool quiet = false;  // no summary on stdout (the demo prints its own)
  // false: no sample frames and no flow.json, only the sweep's or crowd sizes' files (the demo's
  // later runs, which share the main run's folder).
  bool main_files = true;
  // --animation: the main run's frames as an animated PNG, impostors | geometry at half size
  // (animation.png; with main_files only).
  bool animation = false;
  std::string scaling_list = "20,100,500,1000,2000,5000,10000";
  // --window-sizes: the impostor windows' sizes, pixels, largest first ("256,128,64,32": the
  // paper's alone).
  std::string window_sizes = "256,128,64,32,16,8";
  int scaling_frames = 10;
};

// Seeded variants of the built-in body beside it in the flow test bed's default crowd.
constexpr int kDefaultVariants = 3;
// The built-in body's LOD set and `variants` seeded variants of it (make_variant, seeds 1..N),
// built into DIR/default.glb, DIR/default_v1.glb, ... (each reused when it is already there and
// newer than the program). flow_model.cpp; bench_flow has none.
Result<std::vector<std::string>> default_flow_models(const std::string& dir, int variants);

// The targets (the paper's results, to be beaten), checked against flow reports (each a
// run's JSON, as `flow --json` prints it): rows {"target", "measured", "met"}, "met" null where no
// run was given for the target. Used by `flow --targets` and by the demo.
struct TargetRuns {
  // Runs that refresh every character every frame, by label ("posture 0"); met if every one is
  // at most 10 % slower than geometry.
  std::vector<std::pair<std::string, const nlohmann::ordered_json*>> worst;
  // Runs at 5, 8 and 17 degrees with the posture test off, by threshold; `view_label` names them
  // in the table, and `view_parts` (optional, reported only) holds the same with part cards.
  std::vector<std::pair<double, const nlohmann::ordered_json*>> view, view_parts;
  std::string view_label = "whole impostors";
  // Runs at 8 degrees, by name: met if one has both 28 dB and 3x.
  std::vector<std::pair<std::string, const nlohmann::ordered_json*>> quality;
  const nlohmann::ordered_json* scaling = nullptr;  // a report's "scaling" list, or none
  std::string scaling_hint = "not run here";       // the 10,000 row's text when it has no such crowd
};
nlohmann::ordered_json check_targets(const TargetRuns& runs);
// check_targets' rows as a Markdown table.
std::string targets_markdown(const nlohmann::ordered_json& rows);
// `v` with `decimals` digits after the point, for reports.
std::string decimal(double v, int decimals = 2);

// Runs `bodybuilder flow` with these arguments: writes its files under a.out and, when given,
// its JSON report into `report`. Returns the exit status.
int run_flow_command(const FlowArgs& a, nlohmann::ordered_json* report);

}  // namespace bb::cli
