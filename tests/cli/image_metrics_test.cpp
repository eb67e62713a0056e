#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "image_metrics.h"

using namespace bb::cli;

TEST(ImageMetrics, PsnrIsExactOnATinyCase) {
  // 2x1 images; one covered pixel differing by 10 in each channel, one uncovered pixel.
  std::vector<unsigned char> a = {100, 100, 100, 255, 0, 0, 0, 0};
  std::vector<unsigned char> b = {110, 110, 110, 255, 0, 0, 0, 0};
  EXPECT_NEAR(psnr_covered(a.data(), b.data(), 2, 1), 10 * std::log10(255.0 * 255.0 / 100.0), 1e-9);
  EXPECT_TRUE(std::isinf(psnr_covered(a.data(), a.data(), 2, 1)));
  // A pixel covered in one image only counts in full.
  std::vector<unsigned char> c = {100, 100, 100, 255, 255, 255, 255, 255};
  double p = psnr_covered(a.data(), c.data(), 2, 1);
  EXPECT_NEAR(p, 10 * std::log10(255.0 * 255.0 / (255.0 * 255.0 / 2)), 1e-9);
  // Frames are premultiplied: a half-covered edge pixel (colour x coverage) against an empty one
  // differs by what it stores, not by that times its alpha again.
  std::vector<unsigned char> e = {50, 50, 50, 128}, z = {0, 0, 0, 0};
  EXPECT_NEAR(psnr_covered(e.data(), z.data(), 1, 1), 10 * std::log10(255.0 * 255.0 / 2500.0), 1e-9);
}

TEST(ImageMetrics, SsimIsOneForEqualImagesAndLowerForNoise) {
  int w = 32, h = 32;
  std::vector<unsigned char> a(w * h * 4), b;
  for (int i = 0; i < w * h; ++i) {
    a[4 * i] = static_cast<unsigned char>((i * 7) % 256);
    a[4 * i + 1] = static_cast<unsigned char>((i * 3) % 256);
    a[4 * i + 2] = 50;
    a[4 * i + 3] = 255;
  }
  EXPECT_NEAR(ssim_covered(a.data(), a.data(), w, h), 1.0, 1e-12);
  b = a;
  for (int i = 0; i < w * h; ++i) b[4 * i] = static_cast<unsigned char>(b[4 * i] ^ ((i * 37) & 0x3f));
  double s = ssim_covered(a.data(), b.data(), w, h);
  EXPECT_LT(s, 0.99);
  EXPECT_GT(s, 0.0);
}
