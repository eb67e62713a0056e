// Animated PNG (APNG, https://wiki.mozilla.org/APNG_Specification): frames of one size added one
// by one, each compressed as it comes (a few tens of KB for the flow test bed's frames), and
// written whole, atomically, at the end. Browsers play it; a viewer without APNG shows frame 0,
// which is also the file's default image. 8-bit RGB or RGBA, every frame whole (no dispose or blend).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "bb/result.h"

namespace bb::cli {

class AnimatedPng {
 public:
  // width x height pixels per frame of `channels` bytes (3: RGB, 4: RGBA, straight alpha); each
  // frame is shown delay_num / delay_den seconds; loops forever. Sizes from 1 to 2^31 - 1, delays
  // from 1/65535 s (0 den: 1/100 s, as the format says).
  AnimatedPng(int width, int height, int channels, std::uint16_t delay_num, std::uint16_t delay_den);

  // Appends a frame (rows top to bottom, width * channels bytes each).
  Status add(const unsigned char* pixels);
  int frames() const { return static_cast<int>(frames_.size()); }
  // The whole file's bytes (an error before the first frame).
  Result<std::string> encode() const;
  // encode(), written to `path` through a temporary file.
  Status write(const std::string& path) const;

 private:
  int width_, height_, channels_;
  std::uint16_t delay_num_, delay_den_;
  std::vector<std::string> frames_;  // each frame's zlib stream (a PNG's IDAT data)
};

// The CRC-32 of PNG chunks (ISO 3309, as zlib's crc32).
std::uint32_t png_crc32(const unsigned char* data, std::size_t size, std::uint32_t crc = 0);

}  // namespace bb::cli
