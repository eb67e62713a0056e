#include "chart.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

#include <stb/stb_easy_font.h>

namespace bb::cli {

std::vector<std::array<float, 4>> text_rects(const std::string& s, float scale) {
  static thread_local char buf[60000];
  std::vector<char> str(s.begin(), s.end());
  str.push_back(0);
  const int quads = stb_easy_font_print(0, 0, str.data(), nullptr, buf, sizeof(buf));
  std::vector<std::array<float, 4>> out;
  for (int q = 0; q < quads; ++q) {
    const float* v = reinterpret_cast<const float*>(buf + q * 4 * 16);  // 4 vertices of x, y, z, colour
    out.push_back({v[0] * scale, v[1] * scale, v[8] * scale, v[9] * scale});
  }
  return out;
}

namespace {

struct Canvas {
  int w, h;
  std::vector<unsigned char> px;
  Canvas(int width, int height) : w(width), h(height), px(static_cast<size_t>(width) * height * 4, 255) {}
  void blend(int x, int y, unsigned rgb, float a) {
    if (x < 0 || y < 0 || x >= w || y >= h || a <= 0) return;
    unsigned char* p = &px[(static_cast<size_t>(y) * w + x) * 4];
    unsigned c[3] = {(rgb >> 16) & 255, (rgb >> 8) & 255, rgb & 255};
    for (int k = 0; k < 3; ++k) p[k] = static_cast<unsigned char>(p[k] * (1 - a) + c[k] * a + 0.5f);
    p[3] = 255;
  }
  void rect(int x0, int y0, int x1, int y1, unsigned rgb) {
    for (int y = std::max(0, y0); y < std::min(h, y1); ++y)
      for (int x = std::max(0, x0); x < std::min(w, x1); ++x) blend(x, y, rgb, 1);
  }
  // A thick anti-aliased segment: coverage from the distance to the segment.
  void line(float x0, float y0, float x1, float y1, unsigned rgb, float width) {
    float r = width * 0.5f;
    int lx = static_cast<int>(std::floor(std::min(x0, x1) - r - 1)), hx = static_cast<int>(std::ceil(std::max(x0, x1) + r + 1));
    int ly = static_cast<int>(std::floor(std::min(y0, y1) - r - 1)), hy = static_cast<int>(std::ceil(std::max(y0, y1) + r + 1));
    float dx = x1 - x0, dy = y1 - y0, len2 = dx * dx + dy * dy;
    for (int y = ly; y <= hy; ++y)
      for (int x = lx; x <= hx; ++x) {
        float px_ = x + 0.5f, py = y + 0.5f;
        float t = len2 > 0 ? std::clamp(((px_ - x0) * dx + (py - y0) * dy) / len2, 0.0f, 1.0f) : 0.0f;
        float ex = x0 + t * dx - px_, ey = y0 + t * dy - py;
        float d = std::sqrt(ex * ex + ey * ey);
        blend(x, y, rgb, std::clamp(r + 0.5f - d, 0.0f, 1.0f));
      }
  }
  // Text with stb_easy_font, scaled; (x, y) is the top-left corner.
  void text(float x, float y, const std::string& s, unsigned rgb, float scale = 2.0f) {
    for (const auto& r : text_rects(s, scale))
      rect(static_cast<int>(x + r[0]), static_cast<int>(y + r[1]), static_cast<int>(x + r[2]), static_cast<int>(y + r[3]), rgb);
  }
  static float text_width(const std::string& s, float scale = 2.0f) {
    std::vector<char> str(s.begin(), s.end());
    str.push_back(0);
    return stb_easy_font_width(str.data()) * scale;
  }
};

std::string fmt(double v) {
  char b[32];
  double a = std::abs(v);
  if (a >= 1000 && a < 1e7 && v == std::floor(v)) std::snprintf(b, sizeof b, "%.0f", v);  // 10000, not 1e+04
  else if (a >= 1000 || (a > 0 && a < 0.01)) std::snprintf(b, sizeof b, "%.3g", v);
  else if (a >= 10) std::snprintf(b, sizeof b, "%.0f", v);
  else std::snprintf(b, sizeof b, "%.2g", v);
  return b;
}

// "Nice" linear ticks covering [lo, hi].
std::vector<double> ticks(double lo, double hi, int target) {
  double span = hi - lo;
  if (span <= 0) return {lo};
  double step = std::pow(10.0, std::floor(std::log10(span / target)));
  for (double m : {1.0, 2.0, 5.0, 10.0})
    if (span / (step * m) <= target) { step *= m; break; }
  std::vector<double> t;
  for (double v = std::ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) t.push_back(std::abs(v) < step * 1e-9 ? 0 : v);
  return t;
}

std::vector<double> log_ticks(double lo, double hi) {
  std::vector<double> t;
  for (double d = std::pow(10.0, std::floor(std::log10(lo))); d <= hi * 1.0001; d *= 10)
    for (double m : {1.0, 2.0, 5.0})
      if (d * m >= lo * 0.9999 && d * m <= hi * 1.0001) t.push_back(d * m);
  return t;
}

}  // namespace

std::vector<unsigned char> render_chart(const Chart& c, int width, int height) {
  Canvas cv(width, height);
  const int left = 90, right = 20, top = 70, bottom = 70;
  // A point a chart cannot place (not finite, or not positive on a logarithmic axis) is left out,
  // and the series' line breaks there.
  auto x_ok = [&](double x) { return std::isfinite(x) && (!c.log_x || x > 0); };
  auto y_ok = [&](double y) { return std::isfinite(y) && (!c.log_y || y > 0); };
  auto placeable = [&](double x, double y) { return x_ok(x) && y_ok(y); };
  double x_lo = 1e300, x_hi = -1e300, y_lo = 1e300, y_hi = -1e300;
  for (const auto& s : c.series)
    for (size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      if (!placeable(s.x[i], s.y[i])) continue;
      x_lo = std::min(x_lo, s.x[i]); x_hi = std::max(x_hi, s.x[i]);
      y_lo = std::min(y_lo, s.y[i]); y_hi = std::max(y_hi, s.y[i]);
    }
  for (double h : c.hlines)
    if (y_ok(h)) { y_lo = std::min(y_lo, h); y_hi = std::max(y_hi, h); }
  for (double v : c.vlines)
    if (x_ok(v)) { x_lo = std::min(x_lo, v); x_hi = std::max(x_hi, v); }
  if (x_lo > x_hi) { x_lo = c.log_x ? 1 : 0; x_hi = c.log_x ? 10 : 1; }
  if (y_lo > y_hi) { y_lo = c.log_y ? 1 : 0; y_hi = c.log_y ? 10 : 1; }
  if (c.y_min != 0 || c.y_max != 0) { y_lo = c.y_min; y_hi = c.y_max; }
  else if (!c.log_y) { y_lo = std::min(0.0, y_lo); y_hi = y_hi + 0.08 * (y_hi - y_lo); }
  if (x_hi == x_lo) {
    if (c.log_x) { x_lo /= 10; x_hi *= 10; } else { x_lo -= 1; x_hi += 1; }
  }
  if (y_hi == y_lo) { y_hi = c.log_y ? y_lo * 10 : y_lo + 1; }
  auto tx = [&](double v) { return c.log_x ? std::log10(v) : v; };
  auto ty = [&](double v) { return c.log_y ? std::log10(v) : v; };
  double X0 = tx(x_lo), X1 = tx(x_hi), Y0 = ty(c.log_y ? y_lo * 0.8 : y_lo), Y1 = ty(c.log_y ? y_hi * 1.25 : y_hi);
  float pw = static_cast<float>(width - left - right), ph = static_cast<float>(height - top - bottom);
  auto sx = [&](double v) { return static_cast<float>(left + (tx(v) - X0) / (X1 - X0) * pw); };
  auto sy = [&](double v) { return static_cast<float>(top + ph - (ty(v) - Y0) / (Y1 - Y0) * ph); };

  cv.text((width - Canvas::text_width(c.title, 2.5f)) / 2, 14, c.title, 0x222222, 2.5f);
  const bool corner = !c.corner_label.empty() && !c.hlines.empty() && !c.vlines.empty() &&
                      placeable(c.vlines[0], c.hlines[0]);
  if (corner)
    cv.rect(static_cast<int>(sx(c.vlines[0])), top, static_cast<int>(left + pw),
            static_cast<int>(std::max(static_cast<float>(top), sy(c.hlines[0]))), 0xe3f2e3);
  // Grid and ticks.
  auto xt = c.log_x ? log_ticks(x_lo, x_hi) : ticks(x_lo, x_hi, 8);
  auto yt = c.log_y ? log_ticks(y_lo * 0.8, y_hi * 1.25) : ticks(Y0, Y1, 7);
  for (double v : xt) {
    float x = sx(v);
    cv.line(x, static_cast<float>(top), x, top + ph, 0xe4e4e4, 1);
    std::string s = fmt(v);
    const float w = Canvas::text_width(s);  // centred under its tick, kept inside the picture
    cv.text(std::clamp(x - w / 2, 2.0f, static_cast<float>(width) - w - 2.0f), top + ph + 8, s, 0x444444);
  }
  for (double v : yt) {
    float y = sy(v);
    if (y < top - 1 || y > top + ph + 1) continue;
    cv.line(static_cast<float>(left), y, left + pw, y, 0xe4e4e4, 1);
    std::string s = fmt(v);
    cv.text(left - 8 - Canvas::text_width(s), y - 6, s, 0x444444);
  }
  if (corner)
    cv.text(sx(c.vlines[0]) + 8, std::max(static_cast<float>(top) + 4, sy(c.hlines[0]) - 20.0f), c.corner_label, 0x2a7a2a);
  for (double h : c.hlines)
    if (y_ok(h)) cv.line(static_cast<float>(left), sy(h), left + pw, sy(h), 0x888888, 1.5f);
  for (double v : c.vlines)
    if (x_ok(v)) cv.line(sx(v), static_cast<float>(top), sx(v), top + ph, 0x888888, 1.5f);
  cv.line(static_cast<float>(left), static_cast<float>(top), static_cast<float>(left), top + ph, 0x222222, 1.5f);
  cv.line(static_cast<float>(left), top + ph, left + pw, top + ph, 0x222222, 1.5f);
  cv.text(left + (pw - Canvas::text_width(c.x_label)) / 2, static_cast<float>(height - 30), c.x_label, 0x222222);
  // Y label, written horizontally above the axis (easy_font has no rotation).
  cv.text(8, static_cast<float>(top - 22), c.y_label, 0x222222);
  // Series.
  for (const auto& s : c.series) {
    for (size_t i = 0; i + 1 < s.x.size() && i + 1 < s.y.size(); ++i)
      if (placeable(s.x[i], s.y[i]) && placeable(s.x[i + 1], s.y[i + 1]))
        cv.line(sx(s.x[i]), sy(s.y[i]), sx(s.x[i + 1]), sy(s.y[i + 1]), s.color, 2.5f);
    for (size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      if (!placeable(s.x[i], s.y[i])) continue;
      int x = static_cast<int>(sx(s.x[i])), y = static_cast<int>(sy(s.y[i]));
      cv.rect(x - 3, y - 3, x + 4, y + 4, s.color);
    }
  }
  // Legend, top right (or bottom left).
  float lw = 0;
  for (const auto& s : c.series) lw = std::max(lw, Canvas::text_width(s.label));
  float ly = c.legend_bottom_left ? top + ph - 8 - 22.0f * static_cast<float>(c.series.size()) : static_cast<float>(top + 8);
  float lx = c.legend_bottom_left ? left + 16.0f : left + pw - lw - 40;
  for (const auto& s : c.series) {
    cv.line(lx, ly + 7, lx + 22, ly + 7, s.color, 3);
    cv.text(lx + 28, ly, s.label, 0x222222);
    ly += 22;
  }
  return cv.px;
}

}  // namespace bb::cli
