#include "image_metrics.h"

#include <cmath>
#include <cstddef>
#include <limits>
#include <vector>

namespace bb::cli {

namespace {

// The squared error of the RGB channels over the pixels covered (alpha > 0) in either image, and
// how many channels were covered in either image and in `a`.
struct CoveredError {
  double se = 0;
  std::size_t either = 0, in_a = 0;
};

CoveredError covered_error(const unsigned char* a, const unsigned char* b, int w, int h) {
  CoveredError e;
  for (std::size_t i = 0; i < static_cast<std::size_t>(w) * h; ++i) {
    const unsigned char* p = a + 4 * i;
    const unsigned char* q = b + 4 * i;
    if (p[3] == 0 && q[3] == 0) continue;
    // The frames hold premultiplied colours (a multisampled edge pixel is colour x coverage over
    // a transparent clear), so a pixel covered in one image only counts in full as it is.
    for (int k = 0; k < 3; ++k) {
      const double d = double(p[k]) - double(q[k]);
      e.se += d * d;
    }
    e.either += 3;
    if (p[3] != 0) e.in_a += 3;
  }
  return e;
}

double covered_psnr(const CoveredError& e) {
  if (e.either == 0 || e.se == 0) return std::numeric_limits<double>::infinity();
  return 10.0 * std::log10(255.0 * 255.0 * static_cast<double>(e.either) / e.se);
}

double reference_psnr(const CoveredError& e) {
  if (e.se == 0) return std::numeric_limits<double>::infinity();
  if (e.in_a == 0) return 0.0;
  return 10.0 * std::log10(255.0 * 255.0 * static_cast<double>(e.in_a) / e.se);
}

}  // namespace

double psnr_covered(const unsigned char* a, const unsigned char* b, int w, int h) {
  return covered_psnr(covered_error(a, b, w, h));
}

double psnr_reference(const unsigned char* ref, const unsigned char* test, int w, int h) {
  return reference_psnr(covered_error(ref, test, w, h));
}

PsnrPair psnr_both(const unsigned char* ref, const unsigned char* test, int w, int h) {
  const CoveredError e = covered_error(ref, test, w, h);
  return {covered_psnr(e), reference_psnr(e)};
}

double ssim_covered(const unsigned char* a, const unsigned char* b, int w, int h) {
  auto luma = [](const unsigned char* p) {  // premultiplied, like the frames
    return 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2];
  };
  std::vector<double> la(static_cast<size_t>(w) * h), lb(la.size());
  std::vector<char> cov(la.size());
  for (size_t i = 0; i < la.size(); ++i) {
    la[i] = luma(a + 4 * i);
    lb[i] = luma(b + 4 * i);
    cov[i] = a[4 * i + 3] != 0 || b[4 * i + 3] != 0;
  }
  const double c1 = (0.01 * 255) * (0.01 * 255), c2 = (0.03 * 255) * (0.03 * 255);
  double sum = 0;
  size_t windows = 0;
  for (int y = 0; y + 8 <= h; y += 4)
    for (int x = 0; x + 8 <= w; x += 4) {
      bool any = false;
      double ma = 0, mb = 0;
      for (int j = 0; j < 8; ++j)
        for (int i = 0; i < 8; ++i) {
          size_t k = static_cast<size_t>(y + j) * w + x + i;
          any |= cov[k] != 0;
          ma += la[k];
          mb += lb[k];
        }
      if (!any) continue;
      ma /= 64;
      mb /= 64;
      double va = 0, vb = 0, cab = 0;
      for (int j = 0; j < 8; ++j)
        for (int i = 0; i < 8; ++i) {
          size_t k = static_cast<size_t>(y + j) * w + x + i;
          va += (la[k] - ma) * (la[k] - ma);
          vb += (lb[k] - mb) * (lb[k] - mb);
          cab += (la[k] - ma) * (lb[k] - mb);
        }
      va /= 63;
      vb /= 63;
      cab /= 63;
      sum += ((2 * ma * mb + c1) * (2 * cab + c2)) / ((ma * ma + mb * mb + c1) * (va + vb + c2));
      ++windows;
    }
  return windows ? sum / windows : 1.0;
}

}  // namespace bb::cli
