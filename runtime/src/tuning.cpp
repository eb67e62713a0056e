// The flow test bed's measured choices for a kind of scene (bb/runtime/tuning.h).
#include "bb/runtime/tuning.h"

namespace bb::runtime {

bool tuned_whole_blended(const ImpostorConfig& c, const TuningScene& s) {
  return !c.part_cards && s.edges == ImpostorEdges::kBlend && s.samples > 1 && c.texels_per_pixel == 1.0f &&
         c.perspective_snapshots;
}

bool tuned_aligned_snapshots(const ImpostorConfig& c, const TuningScene& s) {
  return tuned_whole_blended(c, s) && c.snapshot_samples == 1 && s.software;
}

int tuned_impostor_taps(const ImpostorConfig& c, const TuningScene& s) {
  if (s.samples == 1) return 1;
  if (c.aligned_snapshots && tuned_whole_blended(c, s)) return 1;
  return !c.part_cards && c.texels_per_pixel <= 1.0f ? 2 : 4;
}

float tuned_aligned_phase(const ImpostorConfig& c, const TuningScene& s) {
  return c.aligned_snapshots && c.impostor_taps == 1 && s.samples > 1 && c.snapshot_samples == 1 ? 0.125f : 0.0f;
}

bool tuned_exact_scale(const ImpostorConfig& c) { return c.perspective_snapshots && !c.part_cards; }

bool tuned_fit_from_vertices(const ImpostorConfig& c, const TuningScene& s) {
  return c.fit_quads_to_coverage && !c.parallax_cards && s.software;
}

namespace {
// Whether the impostors' target has the scene's samples (its own, or the scene's).
bool target_has_scene_samples(const TuningScene& s) {
  return (s.impostor_samples > 0 ? s.impostor_samples : s.samples) == s.samples;
}
}  // namespace

bool tuned_short_lived_as_geometry(const TuningScene& s) {
  return s.adaptive_target || (target_has_scene_samples(s) && (s.samples == 1 || !s.software));
}

std::size_t snapshot_triangles(const Model& model, bool part_cards) {
  const std::size_t triangles = model.lods.empty() ? std::size_t{0} : model.lods.front().triangle_count();
  const std::size_t parts = part_cards ? model.body_parts().size() : 0;
  return parts > 1 ? (triangles + parts / 2) / parts : triangles;
}

bool tuned_short_lived_as_geometry(const TuningScene& s, std::size_t triangles) {
  if (tuned_short_lived_as_geometry(s)) return true;
  return triangles > 0 && triangles < kFewTriangles && (s.adaptive_target || target_has_scene_samples(s));
}

ImpostorConfig tuned_config(ImpostorConfig base, const TuningScene& scene, const Model& model) {
  ImpostorConfig c = tuned_config(base, scene);
  c.short_lived_as_geometry = tuned_short_lived_as_geometry(scene, snapshot_triangles(model, c.part_cards));
  return c;
}

ImpostorConfig tuned_config(ImpostorConfig base, const TuningScene& scene) {
  ImpostorConfig c = base;
  c.aligned_snapshots = tuned_aligned_snapshots(c, scene);
  c.impostor_taps = tuned_impostor_taps(c, scene);
  c.aligned_phase = tuned_aligned_phase(c, scene);
  c.texel_per_pixel = tuned_exact_scale(c);
  c.fit_quads_from_vertices = tuned_fit_from_vertices(c, scene);
  c.short_lived_as_geometry = tuned_short_lived_as_geometry(scene);
  return c;
}

}  // namespace bb::runtime
