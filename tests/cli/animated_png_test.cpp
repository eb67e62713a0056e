// cli/support/animated_png: the file read back chunk by chunk with zlib (CRCs, inflated and
// unfiltered frames equal to the pixels given), and played back by UPNG.js where it is installed.
#include "animated_png.h"

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <zlib.h>

#include "run_cli.h"

namespace {

std::uint32_t be32(const std::string& s, std::size_t at) {
  auto b = [&](std::size_t k) { return static_cast<std::uint32_t>(static_cast<unsigned char>(s[at + k])); };
  return (b(0) << 24) | (b(1) << 16) | (b(2) << 8) | b(3);
}

struct Chunk {
  std::string type, data;
};

// Every chunk after the signature; fails the test on a bad length or CRC.
std::vector<Chunk> chunks(const std::string& file) {
  std::vector<Chunk> out;
  EXPECT_EQ(file.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  for (std::size_t at = 8; at < file.size();) {
    if (at + 12 > file.size()) {
      ADD_FAILURE() << "truncated chunk at byte " << at;
      break;
    }
    const std::uint32_t len = be32(file, at);
    if (at + 12 + len > file.size()) {
      ADD_FAILURE() << "chunk at byte " << at << " runs past the end";
      break;
    }
    const auto* p = reinterpret_cast<const Bytef*>(file.data() + at + 4);
    EXPECT_EQ(crc32(0L, p, len + 4), be32(file, at + 8 + len)) << "CRC of the chunk at byte " << at;
    out.push_back({file.substr(at + 4, 4), file.substr(at + 8, len)});
    at += 12 + len;
  }
  return out;
}

// Inflates a frame's zlib stream and undoes the PNG row filters (8-bit RGB).
std::vector<unsigned char> decode_rgb(const std::string& z, int w, int h) {
  const std::size_t stride = static_cast<std::size_t>(w) * 3;
  std::vector<unsigned char> raw((stride + 1) * h);
  uLongf n = raw.size();
  EXPECT_EQ(uncompress(raw.data(), &n, reinterpret_cast<const Bytef*>(z.data()), z.size()), Z_OK);
  EXPECT_EQ(n, raw.size());
  std::vector<unsigned char> px(stride * h);
  for (int y = 0; y < h; ++y) {
    const unsigned char filter = raw[y * (stride + 1)];
    for (std::size_t x = 0; x < stride; ++x) {
      const int a = x >= 3 ? px[y * stride + x - 3] : 0;
      const int b = y > 0 ? px[(y - 1) * stride + x] : 0;
      const int c = x >= 3 && y > 0 ? px[(y - 1) * stride + x - 3] : 0;
      int pred = 0;
      switch (filter) {
        case 0: pred = 0; break;
        case 1: pred = a; break;
        case 2: pred = b; break;
        case 3: pred = (a + b) / 2; break;
        case 4: {
          const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
          pred = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
          break;
        }
        default: ADD_FAILURE() << "row " << y << ": filter " << int(filter);
      }
      px[y * stride + x] = static_cast<unsigned char>(raw[y * (stride + 1) + 1 + x] + pred);
    }
  }
  return px;
}

}  // namespace

TEST(AnimatedPng, FramesReadBackExactlyInOrder) {
  const int w = 7, h = 5;
  // Three frames that differ everywhere: a gradient, its inverse, noise.
  std::vector<std::vector<unsigned char>> frames(3, std::vector<unsigned char>(w * h * 3));
  std::uint32_t seed = 12345;
  for (int i = 0; i < w * h * 3; ++i) {
    frames[0][i] = static_cast<unsigned char>(i * 7);
    frames[1][i] = static_cast<unsigned char>(255 - i * 7);
    seed = seed * 1664525u + 1013904223u;
    frames[2][i] = static_cast<unsigned char>(seed >> 24);
  }
  bb::cli::AnimatedPng apng(w, h, 3, 1, 30);
  for (const auto& f : frames) ASSERT_TRUE(apng.add(f.data()));
  EXPECT_EQ(apng.frames(), 3);
  auto file = apng.encode();
  ASSERT_TRUE(file) << file.error().message();
  const std::vector<Chunk> c = chunks(*file);
  std::vector<std::string> types;
  for (const Chunk& k : c) types.push_back(k.type);
  EXPECT_EQ(types, (std::vector<std::string>{"IHDR", "acTL", "fcTL", "IDAT", "fcTL", "fdAT", "fcTL", "fdAT", "IEND"}));
  ASSERT_EQ(c.size(), 9u);
  EXPECT_EQ(be32(c[0].data, 0), 7u);
  EXPECT_EQ(be32(c[0].data, 4), 5u);
  EXPECT_EQ(c[0].data.substr(8), std::string("\x08\x02\x00\x00\x00", 5));
  EXPECT_EQ(be32(c[1].data, 0), 3u);  // frames
  EXPECT_EQ(be32(c[1].data, 4), 0u);  // plays forever
  // Sequence numbers 0..4 over fcTL and fdAT; each frame whole, 1/30 s.
  std::uint32_t next = 0;
  std::vector<std::string> streams;
  for (const Chunk& k : c) {
    if (k.type == "fcTL") {
      ASSERT_EQ(k.data.size(), 26u);
      EXPECT_EQ(be32(k.data, 0), next++);
      EXPECT_EQ(be32(k.data, 4), 7u);
      EXPECT_EQ(be32(k.data, 8), 5u);
      EXPECT_EQ(be32(k.data, 12), 0u);
      EXPECT_EQ(be32(k.data, 16), 0u);
      EXPECT_EQ(k.data.substr(20), std::string("\x00\x01\x00\x1e\x00\x00", 6));
    } else if (k.type == "fdAT") {
      EXPECT_EQ(be32(k.data, 0), next++);
      streams.push_back(k.data.substr(4));
    } else if (k.type == "IDAT") {
      streams.push_back(k.data);
    }
  }
  EXPECT_EQ(next, 5u);
  ASSERT_EQ(streams.size(), 3u);
  for (int f = 0; f < 3; ++f) EXPECT_EQ(decode_rgb(streams[f], w, h), frames[f]) << "frame " << f;
  // The CRC is zlib's.
  const std::string abc = "123456789";
  EXPECT_EQ(bb::cli::png_crc32(reinterpret_cast<const unsigned char*>(abc.data()), abc.size()), 0xcbf43926u);
}

TEST(AnimatedPng, NoFramesIsAnErrorAndNothingIsWritten) {
  bb::cli::AnimatedPng apng(4, 4, 3, 1, 10);
  const std::filesystem::path p = std::filesystem::temp_directory_path() / "bb_apng_empty.png";
  std::filesystem::remove(p);
  auto st = apng.write(p.string());
  ASSERT_FALSE(st);
  EXPECT_NE(st.error().message().find("at least one frame"), std::string::npos) << st.error().message();
  EXPECT_NE(st.error().message().find(p.string()), std::string::npos) << st.error().message();
  EXPECT_FALSE(std::filesystem::exists(p));
}

// UPNG.js (tools/, npm), a decoder of its own, plays the file back: every frame whole, at its
// delay, with the pixels given, RGB and RGBA (straight alpha, as PNG holds it).
TEST(AnimatedPng, UpngDecodesEveryFrame) {
  const std::string tool = std::string(BB_SOURCE_DIR) + "/tools/apng_frames.js";
  if (!std::filesystem::exists(std::string(BB_SOURCE_DIR) + "/tools/node_modules/upng-js/package.json"))
    GTEST_SKIP() << "upng-js not installed (run scripts/setup.sh)";
  const int w = 64, h = 32;
  for (const int channels : {3, 4}) {
    SCOPED_TRACE(channels);
    bb::cli::AnimatedPng apng(w, h, channels, 1, 25);
    std::vector<std::uint32_t> hashes;
    std::vector<unsigned char> px(w * h * channels);
    for (int f = 0; f < 4; ++f) {
      for (int i = 0; i < w * h; ++i) {
        const int x = i % w, y = i / w;
        unsigned char* p = &px[channels * i];
        p[0] = static_cast<unsigned char>(x * 4 + f * 16);
        p[1] = static_cast<unsigned char>(y * 8);
        p[2] = static_cast<unsigned char>((x + y + f) % 2 ? 200 : 40);
        if (channels == 4) p[3] = static_cast<unsigned char>((x * 3 + y * 5 + f * 60) % 256);
      }
      ASSERT_TRUE(apng.add(px.data()));
      std::uint32_t hash = 0x811c9dc5u;  // FNV-1a over RGBA8, as the tool hashes what it decoded
      for (int i = 0; i < w * h; ++i)
        for (int k = 0; k < 4; ++k) {
          hash ^= k < channels ? px[channels * i + k] : 255u;
          hash *= 0x01000193u;
        }
      hashes.push_back(hash);
    }
    const std::filesystem::path p = std::filesystem::temp_directory_path() / "bb_apng_upng.png";
    ASSERT_TRUE(apng.write(p.string()));
    const bb::test::CliRun play = bb::test::run_command("node " + tool + " " + p.string());
    ASSERT_EQ(play.status, 0) << play.text;
    const auto j = nlohmann::json::parse(play.text);
    EXPECT_EQ(j["width"], w);
    EXPECT_EQ(j["height"], h);
    EXPECT_EQ(j["ctype"], channels == 4 ? 6 : 2);  // RGBA or RGB
    EXPECT_EQ(j["plays"], 0);                      // forever
    ASSERT_EQ(j["frames"], 4);
    for (int f = 0; f < 4; ++f) {
      const auto& fr = j["frame"][f];
      EXPECT_EQ(fr["rect"], nlohmann::json::array({0, 0, w, h}));
      EXPECT_EQ(fr["delay_ms"], 40);
      EXPECT_EQ(fr["fnv1a"].get<std::uint32_t>(), hashes[f]) << "frame " << f;
    }
  }
}
