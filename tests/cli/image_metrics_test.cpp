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

TEST(ImageMetrics, ReferencePsnrCountsAHaloAsErrorNotAsPixels) {
  // 3x1: the reference covers pixel 0; the test image matches it but for 10 in each channel, and
  // adds a faint halo (alpha 2/255) on pixels 1 and 2.
  std::vector<unsigned char> ref = {100, 100, 100, 255, 0, 0, 0, 0, 0, 0, 0, 0};
  std::vector<unsigned char> bare = {110, 110, 110, 255, 0, 0, 0, 0, 0, 0, 0, 0};
  std::vector<unsigned char> halo = {110, 110, 110, 255, 1, 1, 1, 2, 1, 1, 1, 2};
  const double bare_db = 10 * std::log10(255.0 * 255.0 / 100.0);
  EXPECT_NEAR(psnr_reference(ref.data(), bare.data(), 3, 1), bare_db, 1e-9);
  EXPECT_NEAR(psnr_covered(ref.data(), bare.data(), 3, 1), bare_db, 1e-9);
  // psnr_covered averages over the halo's pixels too: (300 + 3 + 3) / 9 per channel, higher.
  EXPECT_NEAR(psnr_covered(ref.data(), halo.data(), 3, 1), 10 * std::log10(255.0 * 255.0 / (306.0 / 9.0)), 1e-9);
  EXPECT_GT(psnr_covered(ref.data(), halo.data(), 3, 1), bare_db + 4.0);
  // Here the halo adds its error over the reference's one pixel: (300 + 6) / 3, lower.
  EXPECT_NEAR(psnr_reference(ref.data(), halo.data(), 3, 1), 10 * std::log10(255.0 * 255.0 / (306.0 / 3.0)), 1e-9);
  EXPECT_LT(psnr_reference(ref.data(), halo.data(), 3, 1), bare_db);
  EXPECT_TRUE(std::isinf(psnr_reference(ref.data(), ref.data(), 3, 1)));
  // Both from one pass: the same numbers.
  const PsnrPair both = psnr_both(ref.data(), halo.data(), 3, 1);
  EXPECT_EQ(both.covered, psnr_covered(ref.data(), halo.data(), 3, 1));
  EXPECT_EQ(both.reference, psnr_reference(ref.data(), halo.data(), 3, 1));
  // A test image over an empty reference: nothing to measure against, 0 dB.
  std::vector<unsigned char> empty(12, 0);
  EXPECT_EQ(psnr_reference(empty.data(), halo.data(), 3, 1), 0.0);
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
