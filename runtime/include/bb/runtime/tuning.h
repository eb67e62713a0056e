// The impostor settings the flow test bed measured best for a kind of scene: what `bodybuilder flow`
// takes for its auto options (docs/flow.md has each with its figures), for a game to start from.
//
//   rt::ImpostorConfig config = rt::tuned_config({}, {.samples = 4, .software = rt::software_rasterizer()});
//
// tuned_config sets the fields below from the scene and from what `base` already says of the
// impostors (part_cards, texels_per_pixel, perspective_snapshots, snapshot_samples, parallax_cards,
// fit_quads_to_coverage); every other field is `base`'s. Each tuned_* function decides one field, for
// a caller that fixes some of them itself, and reads only the fields it names (in the order of
// tuned_config: the grid, then the taps, then the phase). Pure functions: no GL call.
#pragma once

#include <cstddef>

#include "bb/runtime/crowd.h"
#include "bb/runtime/renderer.h"

namespace bb::runtime {

// The scene the impostors are drawn into.
struct TuningScene {
  int samples = 4;  // samples per pixel of the scene's target (1: single-sampled)
  // A software rasterizer such as Mesa's llvmpipe (software_rasterizer() of the current context),
  // where fill and multisampling cost far more against vertex work than on a GPU.
  bool software = false;
  ImpostorEdges edges = ImpostorEdges::kBlend;  // DrawOptions::edges
  // The impostors' own target, where it is not the scene's (the flow test bed draws each path into
  // a target of its own): its samples per pixel (0: the scene's, as for a game that draws impostors
  // and geometry into one framebuffer), and whether it takes the scene's samples for a frame after
  // one that drew a short-lived character as geometry (the test bed's adaptive target).
  int impostor_samples = 0;
  bool adaptive_target = false;
};

// Whole impostors with blended edges at one texel per pixel from perspective snapshots, in a
// multisampled scene: where the pixel grid and one tap pay (reads part_cards, texels_per_pixel,
// perspective_snapshots).
bool tuned_whole_blended(const ImpostorConfig& c, const TuningScene& s);

// ImpostorConfig::aligned_snapshots: snapshots cut out of the screen's image on its pixel grid, for
// whole blended impostors (tuned_whole_blended) from single-sampled snapshots (snapshot_samples 1)
// on a software rasterizer. There, fortieth session, 4x MSAA: every impostor fresh 27.74 against
// 26.72 dB over the geometry's pixels (two taps on the free grid), the main run 9.8-10.0x against
// 9.3-9.5x for 0.11 dB less; what it buys is one tap's fill. A GPU fills two taps at no cost and
// keeps the free grid: on the H200 (fifty-second session) the main run 0.64-0.67x of geometry's speed
// on the grid against 0.70-0.71x on the free grid, at 12.6 against 12.8 dB, and a GPU draws a
// fresh (short-lived) character as geometry anyway (tuned_short_lived_as_geometry).
bool tuned_aligned_snapshots(const ImpostorConfig& c, const TuningScene& s);

// ImpostorConfig::impostor_taps, given c.aligned_snapshots: 1 in a single-sampled scene (no coverage
// to match) and for whole blended impostors on the pixel grid; 2 for other whole impostors at up to
// one texel per pixel (0.03-0.17 dB below four, the impostor frame 5-25 % shorter); 4 for part cards
// and finer windows (where two lose 0.2-0.4 dB).
int tuned_impostor_taps(const ImpostorConfig& c, const TuningScene& s);

// ImpostorConfig::aligned_phase (pixels), given c.aligned_snapshots and c.impostor_taps: 1/8 for one
// tap over single-sampled snapshots on the pixel grid of a multisampled scene (the tap's bilinear
// weights then soften a fresh snapshot's edges about as the scene's four samples do); else 0.
float tuned_aligned_phase(const ImpostorConfig& c, const TuningScene& s);

// ImpostorConfig::texel_per_pixel (snapshots drawn at the texels per pixel asked, in part of their
// window): for whole impostors from perspective snapshots (faster at every threshold, the same PSNR
// from posture 0.1 and 1 degree up); part cards fill their windows (1.2 dB better at 8 degrees).
bool tuned_exact_scale(const ImpostorConfig& c);

// ImpostorConfig::fit_quads_from_vertices: with fit_quads_to_coverage, fit on the CPU from the
// snapshot's vertices on a software rasterizer (where the coverage pass's barrier finishes the
// frame's drawing so far: part cards at 8 degrees 11 % faster on llvmpipe), but not for
// depth-corrected cards (parallax_cards), which need the pass; a GPU keeps the pass (the fit's
// planning made the H200's frames 10-20 % slower).
bool tuned_fit_from_vertices(const ImpostorConfig& c, const TuningScene& s);

// ImpostorConfig::short_lived_as_geometry: where a character drawn as geometry in an impostor frame
// is the geometry's own picture (the impostors' target has the scene's samples, or is adaptive) and a
// snapshot costs what drawing the character does or more: in a single-sampled scene, and on a GPU
// (the H200's worst case 0.45-0.65x of geometry's speed with snapshots, 0.95-1.03x with geometry). On
// a software rasterizer a multisampled scene's single-sampled snapshot is the cheaper.
bool tuned_short_lived_as_geometry(const TuningScene& s);

// A character of fewer triangles than this at its finest level costs less to draw than its impostor:
// a quad and its refreshes cost about what drawing a few dozen triangles does (flow test bed,
// llvmpipe: SimpleSkin, 8 triangles, 1.1-1.3x geometry's speed at 5 / 8 / 17 degrees and its worst
// case 1.22 of geometry's time with snapshots; the Fox's 576 and RiggedSimple's 188 4-8x).
inline constexpr std::size_t kFewTriangles = 150;

// The triangles a snapshot of `model` draws, as the rule below counts them: its finest level's, or
// with part cards a part's on average (rounded; the finest level's for a model of one part); 0 for
// a model with no level.
std::size_t snapshot_triangles(const Model& model, bool part_cards);

// tuned_short_lived_as_geometry for a model of `triangles` triangles at its finest level (0: not
// known): also,
// for one of fewer than kFewTriangles, wherever a character drawn as geometry is the geometry's own
// picture (the impostors' target has the scene's samples, or is adaptive) on a software rasterizer
// too, a snapshot of so few triangles costing more than drawing them (SimpleSkin's worst case, 4x,
// adaptive target: 0.98-1.06x geometry's speed against 0.66-0.73x with snapshots).
bool tuned_short_lived_as_geometry(const TuningScene& s, std::size_t triangles);

// `base` with every field above tuned for `scene` (and, given the model, short_lived_as_geometry for
// its triangles at its finest level; with part cards, a part's on average, a card's snapshot costing
// what its part's triangles do: the Fox's 16 parts of 36 triangles, worst case 0.46x geometry's speed
// with snapshots, 1.04x with geometry in the adaptive target; RiggedSimple's 2 of 94, 0.80x and 1.00x).
ImpostorConfig tuned_config(ImpostorConfig base, const TuningScene& scene);
ImpostorConfig tuned_config(ImpostorConfig base, const TuningScene& scene, const Model& model);

}  // namespace bb::runtime
