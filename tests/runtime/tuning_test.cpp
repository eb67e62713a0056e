// bb/runtime/tuning.h: the flow test bed's measured choices, field by field, on the cases flow's auto
// options meet (FlowCli.TwoTapsComeCloseToFourInAMultisampledScene checks the same through the CLI).
#include "bb/runtime/tuning.h"

#include <filesystem>
#include <string>

#include <gtest/gtest.h>

namespace bb::runtime {
namespace {

// The test bed's whole impostors: one texel per pixel, perspective, single-sampled snapshots.
ImpostorConfig whole() {
  ImpostorConfig c;
  c.texels_per_pixel = 1.0f;
  return c;
}

TEST(Tuning, TheGridTapsAndPhaseOfFlowsAutoOptions) {
  struct Case {
    const char* what;
    ImpostorConfig base;
    TuningScene scene;
    bool grid;
    int taps;
    float phase;
  };
  ImpostorConfig parts = whole(), fine = whole(), ortho = whole(), exact = whole();
  parts.part_cards = true;
  fine.texels_per_pixel = 2.0f;
  ortho.perspective_snapshots = false;
  exact.snapshot_samples = 4;
  const TuningScene x4{.samples = 4, .software = true}, x1{.samples = 1, .software = true},
      coverage{.samples = 4, .software = true, .edges = ImpostorEdges::kAlphaToCoverage}, gpu4{.samples = 4};
  const Case cases[] = {
      {"whole impostors, 4x", whole(), x4, true, 1, 0.125f},
      {"whole impostors, 4x, on a GPU", whole(), gpu4, false, 2, 0.0f},
      {"part cards", parts, x4, false, 4, 0.0f},
      {"2 texels per pixel", fine, x4, false, 4, 0.0f},
      {"alpha to coverage", whole(), coverage, false, 2, 0.0f},
      {"orthographic snapshots", ortho, x4, false, 2, 0.0f},
      {"one sample", whole(), x1, false, 1, 0.0f},
      {"multisampled snapshots", exact, x4, false, 2, 0.0f},
  };
  for (const Case& k : cases) {
    const ImpostorConfig c = tuned_config(k.base, k.scene);
    EXPECT_EQ(c.aligned_snapshots, k.grid) << k.what;
    EXPECT_EQ(c.impostor_taps, k.taps) << k.what;
    EXPECT_EQ(c.aligned_phase, k.phase) << k.what;
  }
  // A caller that fixes the grid or the taps: each function reads what is decided.
  ImpostorConfig c = whole();
  c.aligned_snapshots = true;
  EXPECT_EQ(tuned_impostor_taps(c, x1), 1);
  c.impostor_taps = 1;
  EXPECT_EQ(tuned_aligned_phase(c, x1), 0.0f);  // one sample: on the pixels
  c.impostor_taps = 2;
  EXPECT_EQ(tuned_aligned_phase(c, x4), 0.0f);  // two taps on the grid: on the pixels
  c.impostor_taps = 1;
  EXPECT_EQ(tuned_aligned_phase(c, x4), 0.125f);
  c.aligned_snapshots = false;
  EXPECT_EQ(tuned_aligned_phase(c, x4), 0.0f);  // the free grid has no phase
  // Only the fields named change.
  ImpostorConfig base = whole();
  base.cache.view_threshold_deg = 17.0f;
  base.windows.count = 3;
  const ImpostorConfig t = tuned_config(base, x4);
  EXPECT_EQ(t.cache.view_threshold_deg, 17.0f);
  EXPECT_EQ(t.windows.count, 3);
  EXPECT_EQ(t.texels_per_pixel, 1.0f);
}

TEST(Tuning, ScaleQuadFitAndShortLivedFollowTheScene) {
  ImpostorConfig c = whole();
  EXPECT_TRUE(tuned_exact_scale(c));
  c.part_cards = true;
  EXPECT_FALSE(tuned_exact_scale(c));  // part cards fill their windows
  c.part_cards = false;
  c.perspective_snapshots = false;
  EXPECT_FALSE(tuned_exact_scale(c));

  ImpostorConfig f = whole();
  const TuningScene gpu{.samples = 4}, sw{.samples = 4, .software = true};
  EXPECT_TRUE(tuned_fit_from_vertices(f, sw));
  EXPECT_FALSE(tuned_fit_from_vertices(f, gpu));  // a GPU keeps the coverage pass
  f.parallax_cards = true;
  EXPECT_FALSE(tuned_fit_from_vertices(f, sw));  // depth-corrected cards need the pass
  f.parallax_cards = false;
  f.fit_quads_to_coverage = false;
  EXPECT_FALSE(tuned_fit_from_vertices(f, sw));  // no fit asked

  // A game's impostors in the scene's own target: geometry for a short-lived character on a GPU and at
  // one sample, a snapshot in a software rasterizer's multisampled scene.
  EXPECT_TRUE(tuned_short_lived_as_geometry({.samples = 4}));
  EXPECT_TRUE(tuned_short_lived_as_geometry({.samples = 1, .software = true}));
  EXPECT_FALSE(tuned_short_lived_as_geometry({.samples = 4, .software = true}));
  // The test bed's single-sampled impostor target of a 4x scene: geometry there only if adaptive.
  EXPECT_FALSE(tuned_short_lived_as_geometry({.samples = 4, .impostor_samples = 1}));
  EXPECT_TRUE(tuned_short_lived_as_geometry({.samples = 4, .impostor_samples = 1, .adaptive_target = true}));
  EXPECT_FALSE(tuned_short_lived_as_geometry({.samples = 4, .software = true, .impostor_samples = 1}));
  // A model of fewer than kFewTriangles (SimpleSkin's 8): geometry wherever that is the geometry's own
  // picture, a software rasterizer's multisampled scene too; not into a single-sampled target of a
  // multisampled scene unless adaptive. 0 triangles: not known, the scene's rule.
  EXPECT_TRUE(tuned_short_lived_as_geometry({.samples = 4, .software = true}, 8));
  EXPECT_FALSE(tuned_short_lived_as_geometry({.samples = 4, .software = true}, kFewTriangles));
  EXPECT_FALSE(tuned_short_lived_as_geometry({.samples = 4, .software = true}, 0));
  EXPECT_FALSE(tuned_short_lived_as_geometry({.samples = 4, .software = true, .impostor_samples = 1}, 8));
  EXPECT_TRUE(tuned_short_lived_as_geometry({.samples = 4, .software = true, .impostor_samples = 1, .adaptive_target = true}, 8));
  EXPECT_TRUE(tuned_short_lived_as_geometry({.samples = 4}, 5000));  // the scene's rule still holds
  Model strip;
  strip.lods.resize(1);
  strip.lods[0].indices.assign(3 * 8, 0);
  EXPECT_TRUE(tuned_config({}, {.samples = 4, .software = true}, strip).short_lived_as_geometry);
  strip.lods[0].indices.assign(3 * 576, 0);
  EXPECT_FALSE(tuned_config({}, {.samples = 4, .software = true}, strip).short_lived_as_geometry);
}

// With part cards the triangles are a card's (its part's on average): the Fox's 576 in 16 parts.
TEST(Tuning, PartCardsCountTheirPartsTriangles) {
  const std::string path = std::string(BB_SHARED_DATA_DIR) + "/gltf/Fox.glb";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data absent: " << path;
  auto fox = load_model(path);
  ASSERT_TRUE(fox.ok()) << fox.error().message();
  ASSERT_EQ(fox->lods.front().triangle_count(), 576u);
  ASSERT_EQ(fox->body_parts().size(), 16u);
  const TuningScene sw{.samples = 4, .software = true};
  EXPECT_FALSE(tuned_config({}, sw, *fox).short_lived_as_geometry);
  EXPECT_TRUE(tuned_config({.part_cards = true}, sw, *fox).short_lived_as_geometry);
}

}  // namespace
}  // namespace bb::runtime
