// Line charts as RGBA images, for the flow test bed's sweeps and scaling results (no plotting
// dependency: axes, ticks, labels with stb_easy_font, lines, markers and a legend).
#pragma once

#include <array>
#include <string>
#include <vector>

namespace bb::cli {

struct Series {
  std::string label;
  std::vector<double> x, y;
  unsigned color = 0x1f77b4;  // 0xRRGGBB
};

struct Chart {
  std::string title, x_label, y_label;
  std::vector<Series> series;
  bool log_x = false, log_y = false;
  double y_min = 0, y_max = 0;  // both 0: from the data (with 0 included on a linear axis)
  std::vector<double> hlines;   // horizontal reference lines (e.g. 1.0 = geometry)
  std::vector<double> vlines;   // vertical reference lines (e.g. a target's speed-up)
  // Where both reference lines' ends meet (the first of each): a shaded corner above and right of
  // them, labelled (a region a target asks for).
  std::string corner_label;
  bool legend_bottom_left = false;  // the legend's corner (default: top right)
};

// The rectangles (x0, y0, x1, y1: pixels from the text's top-left corner, ends excluded) that
// spell `s` in stb_easy_font at `scale`, to write a label into any image.
std::vector<std::array<float, 4>> text_rects(const std::string& s, float scale = 2.0f);

// Renders the chart into width x height RGBA8 pixels (rows top to bottom).
std::vector<unsigned char> render_chart(const Chart& chart, int width, int height);

}  // namespace bb::cli
