// Image comparison for the flow test bed: PSNR over covered pixels and SSIM (luma, 8x8 windows).
#pragma once

#include <cstddef>

namespace bb::cli {

// Both images hold premultiplied RGBA8 (colour x coverage), as the renderer's frames do.
// PSNR in dB of the RGB channels over pixels covered (alpha > 0) in either image;
// +infinity when they are equal there, 0 covered pixels gives +infinity too.
double psnr_covered(const unsigned char* a, const unsigned char* b, int width, int height);

// Mean SSIM of the luma over 8x8 windows (stride 4) that hold a covered pixel in either image.
double ssim_covered(const unsigned char* a, const unsigned char* b, int width, int height);

}  // namespace bb::cli
