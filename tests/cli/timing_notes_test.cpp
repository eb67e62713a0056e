#include "timing_notes.h"

#include <vector>

#include <gtest/gtest.h>

using namespace bb::cli;

TEST(TimingNotes, GeometrySpreadIsTheLargestOverTheSmallest) {
  EXPECT_EQ(geometry_spread(std::vector<double>{}), 0.0);
  EXPECT_EQ(geometry_spread(std::vector<double>{0.0, 0.0}), 0.0);  // no geometry measured
  EXPECT_EQ(geometry_spread(std::vector<double>{2.0, 2.0, 2.0}), 1.0);
  EXPECT_DOUBLE_EQ(geometry_spread(std::vector<double>{1.5, 3.0, 2.0}), 2.0);
  EXPECT_DOUBLE_EQ(geometry_spread(std::vector<double>{0.0, 1.0, 4.0}), 4.0);  // a path that did not run: left out
}

TEST(TimingNotes, OnlyADriftBeyondNoiseIsNoted) {
  // The demos' sweeps on llvmpipe (noise) and the H200's 1,000-human view sweep (fifty-second session).
  const std::vector<double> llvmpipe{15.0, 16.1, 20.6, 21.3, 16.5, 19.6, 19.9, 16.2, 16.6};
  const std::vector<double> h200{1.318, 1.381, 1.603, 1.948, 2.213, 2.460, 2.675, 2.948, 3.145, 3.353};
  EXPECT_FALSE(drift_note(geometry_spread(llvmpipe)).has_value());
  const auto note = drift_note(geometry_spread(h200));
  ASSERT_TRUE(note.has_value());
  EXPECT_NE(note->find("2.5x longer"), std::string::npos) << *note;
  EXPECT_FALSE(drift_note(0.0).has_value());
  EXPECT_TRUE(drift_note(kDriftNoteSpread).has_value());
}
