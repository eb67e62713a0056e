// What a loaded model holds that the runtime does not draw as the file says, one line each, for the
// commands that draw anyone's model (flow, render) to print and report.
#pragma once

#include <string>
#include <vector>

#include "bb/runtime/model.h"

namespace bb::cli {

inline std::vector<std::string> model_notes(const runtime::Model& m) {
  std::vector<std::string> notes;
  const runtime::MorphReport& morph = m.morph_report;
  if (morph.weight_channels > 0)
    notes.push_back(std::to_string(morph.weight_channels) +
                    " animated morph weight channel(s) not played: the morph targets are drawn at their default weights");
  const runtime::SkinReport& skin = m.skin_report;
  if (skin.vertices_over_four > 0)
    notes.push_back(std::to_string(skin.vertices_over_four) +
                    " vertices have more than 4 joint influences: the 4 heaviest are kept (at most " +
                    std::to_string(static_cast<int>(100.0 * skin.worst_dropped_weight + 0.5)) + " % of a weight dropped)");
  return notes;
}

}  // namespace bb::cli
