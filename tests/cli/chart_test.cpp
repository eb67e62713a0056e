#include <cmath>

#include <gtest/gtest.h>

#include "chart.h"

using namespace bb::cli;

TEST(Chart, DrawsSeriesInTheirColoursInsideThePlot) {
  Chart c;
  c.title = "t";
  c.series.push_back({"a", {0, 1, 2}, {0, 1, 2}, 0xff0000});
  c.series.push_back({"b", {0, 1, 2}, {2, 1, 0}, 0x0000ff});
  auto px = render_chart(c, 400, 300);
  ASSERT_EQ(px.size(), 400u * 300 * 4);
  size_t red = 0, blue = 0;
  for (size_t i = 0; i < px.size(); i += 4) {
    EXPECT_EQ(px[i + 3], 255);
    red += px[i] == 255 && px[i + 1] == 0 && px[i + 2] == 0;
    blue += px[i] == 0 && px[i + 1] == 0 && px[i + 2] == 255;
  }
  EXPECT_GT(red, 200u);
  EXPECT_GT(blue, 200u);
}

TEST(Chart, LogAxesAndEmptyChartsDoNotBreak) {
  Chart c;
  c.log_x = c.log_y = true;
  c.series.push_back({"s", {20, 100, 1000, 10000}, {1, 3, 30, 300}, 0x00aa00});
  EXPECT_EQ(render_chart(c, 300, 200).size(), 300u * 200 * 4);
  Chart empty;
  EXPECT_EQ(render_chart(empty, 100, 100).size(), 100u * 100 * 4);
}

// Reference lines both ways, and the corner they bound (a target's region) shaded: only above
// the horizontal line and right of the vertical one, inside the plot.
TEST(Chart, TheCornerOfTheReferenceLinesIsShaded) {
  Chart c;
  c.series.push_back({"s", {1, 5}, {12, 30}, 0x0000ff});
  c.hlines = {28};
  c.vlines = {3};
  c.y_min = 10;
  c.y_max = 32;
  c.corner_label = "x";
  c.legend_bottom_left = true;
  const int w = 600, h = 400;
  auto px = render_chart(c, w, h);
  // The plot: 90 pixels left, 20 right, 70 top and bottom; x from 1 to 5, y from 10 to 32.
  const float x3 = 90 + (3.0f - 1) / 4 * 490, y28 = 70 + 260 - (28.0f - 10) / 22 * 260;
  int shaded = 0, outside = 0, grey_rows = 0;
  for (int y = 0; y < h; ++y) {
    bool grey = false;
    for (int x = 0; x < w; ++x) {
      const unsigned char* p = &px[(static_cast<size_t>(y) * w + x) * 4];
      if (p[0] == 0xe3 && p[1] == 0xf2 && p[2] == 0xe3) {
        ++shaded;
        outside += x < x3 - 1 || x > 580 || y < 70 || y > y28 + 1;
      }
      // The vertical line, anti-aliased: grey on the pixels beside x = 3.
      grey |= std::abs(x + 0.5f - x3) < 1 && p[0] == p[1] && p[1] == p[2] && p[0] < 0xd0;
    }
    grey_rows += grey;
  }
  EXPECT_GT(shaded, (580 - x3) * (y28 - 70) / 2);  // most of it (grid lines and the label cross it)
  EXPECT_EQ(outside, 0);
  EXPECT_GT(grey_rows, 200);  // the vertical line, nearly the plot's height of 260
}

// A logarithmic axis cannot place zero or negative values (flow --mode impostor --scaling has a
// geometry time of 0): those points are left out, with the line broken there, and the rest drawn.
// The chart took the log of 0 for its ticks before and ran out of memory.
TEST(Chart, LogAxesLeaveOutWhatTheyCannotPlace) {
  Chart c;
  c.log_x = c.log_y = true;
  c.series.push_back({"zeros", {20, 100, 1000}, {0, 0, -1}, 0xff0000});
  c.series.push_back({"times", {20, 100, 0, 1000}, {1, 3, 5, 30}, 0x0000ff});
  c.hlines = {0};
  auto px = render_chart(c, 400, 300);
  ASSERT_EQ(px.size(), 400u * 300 * 4);
  size_t red = 0, blue = 0;
  for (size_t i = 0; i < px.size(); i += 4) {
    red += px[i] == 255 && px[i + 1] == 0 && px[i + 2] == 0;
    blue += px[i] == 0 && px[i + 1] == 0 && px[i + 2] == 255;
  }
  // The legend's line of the zero series is all of its colour: 22 by 3 pixels and anti-aliased ends.
  EXPECT_LT(red, 120u);
  EXPECT_GT(blue, 200u);
  // Nothing placeable at all: an empty frame, not a crash.
  Chart none;
  none.log_x = none.log_y = true;
  none.series.push_back({"zeros", {0, 0}, {0, 0}, 0xff0000});
  EXPECT_EQ(render_chart(none, 200, 100).size(), 200u * 100 * 4);
}
