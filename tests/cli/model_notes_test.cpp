// model_notes: a line for each thing the runtime does not draw as the file says, none for a model
// it draws as given.
#include <gtest/gtest.h>

#include "model_notes.h"

namespace bb::cli {
namespace {

TEST(ModelNotes, NameWhatIsNotDrawnAsTheFileSays) {
  runtime::Model m;
  EXPECT_TRUE(model_notes(m).empty());
  m.morph_report.primitives = 2;  // targets at their default weights: drawn as the file says
  m.morph_report.weighted_targets = 3;
  EXPECT_TRUE(model_notes(m).empty());
  m.morph_report.weight_channels = 2;
  m.skin_report.vertices_over_four = 17;
  m.skin_report.worst_dropped_weight = 0.126;
  const auto notes = model_notes(m);
  ASSERT_EQ(notes.size(), 2u);
  EXPECT_EQ(notes[0], "2 animated morph weight channel(s) not played: the morph targets are drawn at their default weights");
  EXPECT_EQ(notes[1], "17 vertices have more than 4 joint influences: the 4 heaviest are kept (at most 13 % of a weight dropped)");
}

}  // namespace
}  // namespace bb::cli
