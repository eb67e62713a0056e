#include <array>
#include <cassert>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#define STB_IMAGE_WRITE_STATIC
#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STBIW_WINDOWS_UTF8
#include <stb/stb_image_write.h>
#include <zlib.h>

#include "../io.h"
#include "animated_png.h"

namespace bb::cli {

Status write_png(const std::string& path, int width, int height, const unsigned char* rgba) {
  std::vector<unsigned char> bytes;
  auto sink = [](void* ctx, void* data, int size) {
    auto* v = static_cast<std::vector<unsigned char>*>(ctx);
    v->insert(v->end(), static_cast<unsigned char*>(data), static_cast<unsigned char*>(data) + size);
  };
  if (!stbi_write_png_to_func(sink, &bytes, width, height, 4, rgba, width * 4))
    return Error{path, "", "PNG encoding failed"};
  return write_atomic(path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

namespace {

void put32(std::string& out, std::uint32_t v) {
  for (int k = 3; k >= 0; --k) out.push_back(static_cast<char>((v >> (8 * k)) & 0xff));
}

void put16(std::string& out, std::uint16_t v) {
  out.push_back(static_cast<char>(v >> 8));
  out.push_back(static_cast<char>(v & 0xff));
}

// length, type, data, CRC of type and data
void chunk(std::string& out, const char type[4], const std::string& data) {
  put32(out, static_cast<std::uint32_t>(data.size()));
  const std::size_t start = out.size();
  out.append(type, 4);
  out += data;
  put32(out, png_crc32(reinterpret_cast<const unsigned char*>(out.data() + start), out.size() - start));
}

}  // namespace

std::uint32_t png_crc32(const unsigned char* data, std::size_t size, std::uint32_t crc) {
  static const auto table = [] {
    std::array<std::uint32_t, 256> t{};
    for (std::uint32_t n = 0; n < 256; ++n) {
      std::uint32_t c = n;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xedb88320u ^ (c >> 1) : c >> 1;
      t[n] = c;
    }
    return t;
  }();
  crc = ~crc;
  for (std::size_t i = 0; i < size; ++i) crc = table[(crc ^ data[i]) & 0xff] ^ (crc >> 8);
  return ~crc;
}

AnimatedPng::AnimatedPng(int width, int height, int channels, std::uint16_t delay_num, std::uint16_t delay_den)
    : width_(width), height_(height), channels_(channels), delay_num_(delay_num), delay_den_(delay_den) {
  assert(width > 0 && height > 0 && (channels == 3 || channels == 4));
}

Status AnimatedPng::add(const unsigned char* pixels) {
  // Each row filtered with PNG's "Up" filter (the first with "Sub"), then deflated by zlib at level
  // 3. stb's encoder (adaptive filters, its own deflate) took 27 % of a 60-frame `flow --animation`
  // run's CPU time, about 4 of its 10.7 s on this machine.
  const std::size_t stride = static_cast<std::size_t>(width_) * channels_;
  std::vector<unsigned char> raw(static_cast<std::size_t>(height_) * (stride + 1));
  for (int y = 0; y < height_; ++y) {
    unsigned char* out = raw.data() + static_cast<std::size_t>(y) * (stride + 1);
    const unsigned char* row = pixels + static_cast<std::size_t>(y) * stride;
    if (y == 0) {
      out[0] = 1;  // Sub
      for (std::size_t i = 0; i < stride; ++i)
        out[1 + i] = static_cast<unsigned char>(row[i] - (i >= std::size_t(channels_) ? row[i - channels_] : 0));
    } else {
      out[0] = 2;  // Up
      const unsigned char* above = row - stride;
      for (std::size_t i = 0; i < stride; ++i) out[1 + i] = static_cast<unsigned char>(row[i] - above[i]);
    }
  }
  uLongf size = compressBound(static_cast<uLong>(raw.size()));
  std::string z(size, '\0');
  if (compress2(reinterpret_cast<Bytef*>(z.data()), &size, raw.data(), static_cast<uLong>(raw.size()), 3) != Z_OK)
    return Error{"", "frame " + std::to_string(frames_.size()), "PNG encoding failed (zlib)"};
  z.resize(size);
  frames_.push_back(std::move(z));
  return Ok{};
}

Result<std::string> AnimatedPng::encode() const {
  if (frames_.empty()) return Error{"", "", "an animated PNG needs at least one frame"};
  std::string out("\x89PNG\r\n\x1a\n", 8);
  std::string d;
  put32(d, static_cast<std::uint32_t>(width_));
  put32(d, static_cast<std::uint32_t>(height_));
  d.push_back(8);                                  // bits per channel
  d.push_back(channels_ == 4 ? 6 : 2);             // RGBA or RGB
  d += std::string("\x00\x00\x00", 3);           // deflate, adaptive filters, no interlace
  chunk(out, "IHDR", d);
  d.clear();
  put32(d, static_cast<std::uint32_t>(frames_.size()));
  put32(d, 0);  // plays: forever
  chunk(out, "acTL", d);
  std::uint32_t sequence = 0;  // fcTL and fdAT chunks, numbered from 0 in file order
  for (std::size_t f = 0; f < frames_.size(); ++f) {
    d.clear();
    put32(d, sequence++);
    put32(d, static_cast<std::uint32_t>(width_));
    put32(d, static_cast<std::uint32_t>(height_));
    put32(d, 0);  // x offset
    put32(d, 0);  // y offset
    put16(d, delay_num_);
    put16(d, delay_den_);
    d.push_back(0);  // dispose: none
    d.push_back(0);  // blend: source
    chunk(out, "fcTL", d);
    if (f == 0) {
      chunk(out, "IDAT", frames_[0]);  // the default image is the first frame
    } else {
      d.clear();
      put32(d, sequence++);
      d += frames_[f];
      chunk(out, "fdAT", d);
    }
  }
  chunk(out, "IEND", {});
  return out;
}

Status AnimatedPng::write(const std::string& path) const {
  auto bytes = encode();
  if (!bytes) return Error{path, "", bytes.error().reason};
  return write_atomic(path, *bytes);
}

}  // namespace bb::cli
