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
