// Image comparison for the flow test bed: PSNR over covered pixels and SSIM (luma, 8x8 windows).
#pragma once

#include <cstddef>

namespace bb::cli {

// Both images hold premultiplied RGBA8 (colour x coverage), as the renderer's frames do.
// PSNR in dB of the RGB channels over pixels covered (alpha > 0) in either image;
// +infinity when they are equal there, 0 covered pixels gives +infinity too.
double psnr_covered(const unsigned char* a, const unsigned char* b, int width, int height);

// PSNR in dB whose mean is over a count that `test` cannot change: the squared error of the RGB
// channels over every pixel covered in either image, divided by the pixels `ref` covers. Under
// psnr_covered a faint halo around `test`'s shapes (alpha 1/255 and up) adds pixels of almost no
// error to the mean and raises the PSNR; here it only adds its error. +infinity when the images
// are equal where covered; 0 when `ref` covers nothing but `test` does.
double psnr_reference(const unsigned char* ref, const unsigned char* test, int width, int height);

// psnr_covered(ref, test) and psnr_reference(ref, test) from one pass over the images.
struct PsnrPair {
  double covered = 0, reference = 0;
};
PsnrPair psnr_both(const unsigned char* ref, const unsigned char* test, int width, int height);

// Mean SSIM of the luma over 8x8 windows (stride 4) that hold a covered pixel in either image.
double ssim_covered(const unsigned char* a, const unsigned char* b, int width, int height);

}  // namespace bb::cli
