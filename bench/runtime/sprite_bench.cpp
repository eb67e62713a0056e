// What the impostor pass's quads could be drawn as, measured alone: N premultiplied sprites of H
// pixels (2:3 wide, random places and depths, drawn back to front) blended into a 1280x1024 RGBA8
// target, headless EGL (llvmpipe without a GPU).
// - InstancedQuads: what the renderer does, one instanced 4-vertex strip a sprite, depth tested.
// - ComputeSplat: the sprites binned on the CPU into TxT-pixel tiles, then one compute invocation a
//   pixel blends its tile's sprites in order into the target (imageLoad / imageStore), so that
//   llvmpipe pays no set-up per primitive. Counter `mse`: squared error against the quads' picture
//   (0-255 per channel), so both draw the same thing.
// Forty-third session, llvmpipe: 10,000 sprites of 4-16 pixels, quads 15-18 ms, the splat 34-58 ms
// (16x16 tiles 58 ms, 8x8 35, 4x4 38-40; 2 ms of it with no sprite read at all); 1,000 sprites 2.3
// against 12-14 ms; 50 sprites of 300-400 pixels 14 against 40 ms. The per-pixel loop over a
// tile's sprites costs llvmpipe more than the primitives it saves, so the renderer keeps its quads
// (docs/results.md, forty-third session).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <random>
#include <string>
#include <vector>

#ifndef GL_GLEXT_PROTOTYPES
#define GL_GLEXT_PROTOTYPES 1
#endif
#include <GL/glcorearb.h>
#include <benchmark/benchmark.h>

#include "bb/runtime/headless.h"

namespace {

constexpr int kW = 1280, kH = 1024, kAtlas = 512, kLayers = 4, kWinW = 32, kWinH = 48;

struct Sprite {
  float rect[4];  // pixels: x0 y0 x1 y1
  float uv[4];    // atlas window
  float ld[4];    // layer, depth in [0, 1]
};

const char* kVs = R"(#version 450 core
layout(location = 0) in vec4 i_rect;
layout(location = 1) in vec4 i_uv;
layout(location = 2) in vec4 i_ld;
uniform vec2 u_size;
out vec3 v_uvl;
void main() {
  vec2 c = vec2(gl_VertexID & 1, gl_VertexID >> 1);
  gl_Position = vec4(mix(i_rect.xy, i_rect.zw, c) / u_size * 2.0 - 1.0, i_ld.y * 2.0 - 1.0, 1.0);
  v_uvl = vec3(mix(i_uv.xy, i_uv.zw, c), i_ld.x);
})";

const char* kFs = R"(#version 450 core
layout(binding = 0) uniform sampler2DArray u_atlas;
in vec3 v_uvl;
out vec4 o_color;
void main() {
  vec4 c = texture(u_atlas, v_uvl);
  if (c.a < 1.0 / 255.0) discard;
  o_color = c;
})";

const char* kCs = R"(#version 450 core
layout(local_size_x = T, local_size_y = T) in;
layout(binding = 0) uniform sampler2DArray u_atlas;
layout(rgba8, binding = 0) uniform image2D u_dst;
struct Sprite { vec4 rect; vec4 uv; vec4 ld; };
layout(std430, binding = 0) readonly buffer Sprites { Sprite sprites[]; };
layout(std430, binding = 1) readonly buffer Offsets { uint offsets[]; };
layout(std430, binding = 2) readonly buffer Lists { uint list[]; };
uniform int u_tiles_x;
void main() {
  uint tile = gl_WorkGroupID.y * uint(u_tiles_x) + gl_WorkGroupID.x;
  uint b = offsets[tile], e = offsets[tile + 1];
  if (b == e) return;
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  vec2 pc = vec2(px) + 0.5;
  vec4 d = imageLoad(u_dst, px);
  bool touched = false;
  for (uint i = b; i < e; ++i) {
    Sprite s = sprites[list[i]];
    if (all(greaterThanEqual(pc, s.rect.xy)) && all(lessThan(pc, s.rect.zw))) {
      vec2 f = (pc - s.rect.xy) / (s.rect.zw - s.rect.xy);
      vec4 c = textureLod(u_atlas, vec3(mix(s.uv.xy, s.uv.zw, f), s.ld.x), 0.0);
      d = c + (1.0 - c.a) * d;
      touched = true;
    }
  }
  if (touched) imageStore(u_dst, px, d);
})";

GLuint compile(GLenum type, const std::string& src, std::string* error) {
  GLuint s = glCreateShader(type);
  const char* p = src.c_str();
  glShaderSource(s, 1, &p, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    glGetShaderInfoLog(s, sizeof log, nullptr, log);
    *error += log;
  }
  return s;
}

GLuint link(const std::vector<GLuint>& shaders, std::string* error) {
  GLuint p = glCreateProgram();
  for (GLuint s : shaders) glAttachShader(p, s);
  glLinkProgram(p);
  GLint ok = 0;
  glGetProgramiv(p, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    glGetProgramInfoLog(p, sizeof log, nullptr, log);
    *error += log;
  }
  for (GLuint s : shaders) glDeleteShader(s);
  return p;
}

struct Scene {
  std::unique_ptr<bb::runtime::HeadlessContext> ctx;
  std::string error;
  GLuint color = 0, depth = 0, fbo = 0, atlas = 0, quad_program = 0, vao = 0, vbo = 0;
  GLuint buffers[3] = {};

  static Scene& get() {
    static Scene s;
    return s;
  }

 private:
  Scene() {
    auto c = bb::runtime::HeadlessContext::create();
    if (!c) {
      error = c.error().message();
      return;
    }
    ctx = std::move(*c);
    glCreateTextures(GL_TEXTURE_2D, 1, &color);
    glTextureStorage2D(color, 1, GL_RGBA8, kW, kH);
    glCreateRenderbuffers(1, &depth);
    glNamedRenderbufferStorage(depth, GL_DEPTH_COMPONENT24, kW, kH);
    glCreateFramebuffers(1, &fbo);
    glNamedFramebufferTexture(fbo, GL_COLOR_ATTACHMENT0, color, 0);
    glNamedFramebufferRenderbuffer(fbo, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth);
    // Windows of 32x48 texels, each an ellipse with a 1/8-radius soft edge, premultiplied.
    std::vector<unsigned char> texels(std::size_t(kAtlas) * kAtlas * 4 * kLayers);
    for (int l = 0; l < kLayers; ++l)
      for (int y = 0; y < kAtlas; ++y)
        for (int x = 0; x < kAtlas; ++x) {
          const float u = (x % kWinW + 0.5f) / kWinW - 0.5f, v = (y % kWinH + 0.5f) / kWinH - 0.5f;
          const float a = std::clamp((1.0f - std::sqrt(u * u / 0.16f + v * v / 0.2f)) * 8.0f, 0.0f, 1.0f);
          unsigned char* t = &texels[((std::size_t(l) * kAtlas + y) * kAtlas + x) * 4];
          t[0] = static_cast<unsigned char>(a * float(100 + (x * 7 + l * 30) % 155));
          t[1] = static_cast<unsigned char>(a * float(80 + y % 120));
          t[2] = static_cast<unsigned char>(a * 60.0f);
          t[3] = static_cast<unsigned char>(a * 255.0f);
        }
    glCreateTextures(GL_TEXTURE_2D_ARRAY, 1, &atlas);
    glTextureStorage3D(atlas, 1, GL_RGBA8, kAtlas, kAtlas, kLayers);
    glTextureSubImage3D(atlas, 0, 0, 0, 0, kAtlas, kAtlas, kLayers, GL_RGBA, GL_UNSIGNED_BYTE, texels.data());
    glTextureParameteri(atlas, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTextureParameteri(atlas, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glCreateBuffers(1, &vbo);
    glCreateVertexArrays(1, &vao);
    for (GLuint i = 0; i < 3; ++i) {
      glEnableVertexArrayAttrib(vao, i);
      glVertexArrayAttribFormat(vao, i, 4, GL_FLOAT, GL_FALSE, i * 16);
      glVertexArrayAttribBinding(vao, i, 0);
    }
    glVertexArrayVertexBuffer(vao, 0, vbo, 0, sizeof(Sprite));
    glVertexArrayBindingDivisor(vao, 0, 1);
    quad_program = link({compile(GL_VERTEX_SHADER, kVs, &error), compile(GL_FRAGMENT_SHADER, kFs, &error)}, &error);
    glCreateBuffers(3, buffers);
  }
};

// N sprites H = hmin..hmax pixels high, seeded, farthest first.
std::vector<Sprite> sprites(int n, int hmin, int hmax) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  std::vector<Sprite> out(static_cast<std::size_t>(n));
  for (Sprite& s : out) {
    const float h = float(hmin) + float(hmax - hmin) * unit(rng), w = h * 2.0f / 3.0f;
    const float x = unit(rng) * (kW - w), y = unit(rng) * (kH - h);
    const int wx = int(rng() % (kAtlas / kWinW)), wy = int(rng() % (kAtlas / kWinH));
    s = Sprite{{x, y, x + w, y + h},
               {float(wx * kWinW) / kAtlas, float(wy * kWinH) / kAtlas, float((wx + 1) * kWinW) / kAtlas,
                float((wy + 1) * kWinH) / kAtlas},
               {float(rng() % kLayers), 0.1f + 0.8f * unit(rng), 0.0f, 0.0f}};
  }
  std::sort(out.begin(), out.end(), [](const Sprite& a, const Sprite& b) { return a.ld[1] > b.ld[1]; });
  return out;
}

void clear(const Scene& s) {
  glBindFramebuffer(GL_FRAMEBUFFER, s.fbo);
  glViewport(0, 0, kW, kH);
  glClearColor(0, 0, 0, 0);
  glClearDepth(1.0);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  glFinish();
}

void draw_quads(const Scene& s, const std::vector<Sprite>& sp) {
  glNamedBufferData(s.vbo, GLsizeiptr(sp.size() * sizeof(Sprite)), sp.data(), GL_STREAM_DRAW);
  glUseProgram(s.quad_program);
  glUniform2f(glGetUniformLocation(s.quad_program, "u_size"), float(kW), float(kH));
  glEnable(GL_BLEND);
  glBlendFunc(GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LEQUAL);
  glBindVertexArray(s.vao);
  glBindTextureUnit(0, s.atlas);
  glDrawArraysInstanced(GL_TRIANGLE_STRIP, 0, 4, GLsizei(sp.size()));
  glFinish();
}

// Bins the sprites into tiles (a sprite in every tile whose pixel centres it may cover), uploads
// them and dispatches a work group a tile.
void draw_splat(const Scene& s, GLuint program, int t, const std::vector<Sprite>& sp) {
  const int tx = (kW + t - 1) / t, ty = (kH + t - 1) / t;
  std::vector<std::uint32_t> offsets(std::size_t(tx) * ty + 1, 0), list;
  auto tiles = [&](const Sprite& q, auto&& f) {
    const int x0 = std::max(0, int(std::floor(q.rect[0] - 0.5f)) / t), x1 = std::min(tx - 1, int(std::floor(q.rect[2] - 0.5f)) / t);
    const int y0 = std::max(0, int(std::floor(q.rect[1] - 0.5f)) / t), y1 = std::min(ty - 1, int(std::floor(q.rect[3] - 0.5f)) / t);
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) f(std::size_t(y) * tx + x);
  };
  for (const Sprite& q : sp) tiles(q, [&](std::size_t i) { ++offsets[i + 1]; });
  for (std::size_t i = 1; i < offsets.size(); ++i) offsets[i] += offsets[i - 1];
  list.resize(offsets.back());
  std::vector<std::uint32_t> fill(offsets.begin(), offsets.end() - 1);
  for (std::uint32_t k = 0; k < sp.size(); ++k) tiles(sp[k], [&](std::size_t i) { list[fill[i]++] = k; });
  list.push_back(0);  // never an empty buffer
  glNamedBufferData(s.buffers[0], GLsizeiptr(sp.size() * sizeof(Sprite)), sp.data(), GL_STREAM_DRAW);
  glNamedBufferData(s.buffers[1], GLsizeiptr(offsets.size() * 4), offsets.data(), GL_STREAM_DRAW);
  glNamedBufferData(s.buffers[2], GLsizeiptr(list.size() * 4), list.data(), GL_STREAM_DRAW);
  glUseProgram(program);
  glUniform1i(glGetUniformLocation(program, "u_tiles_x"), tx);
  glBindTextureUnit(0, s.atlas);
  glBindImageTexture(0, s.color, 0, GL_FALSE, 0, GL_READ_WRITE, GL_RGBA8);
  for (GLuint i = 0; i < 3; ++i) glBindBufferBase(GL_SHADER_STORAGE_BUFFER, i, s.buffers[i]);
  glDispatchCompute(GLuint(tx), GLuint(ty), 1);
  glMemoryBarrier(GL_FRAMEBUFFER_BARRIER_BIT | GL_TEXTURE_UPDATE_BARRIER_BIT);
  glFinish();
}

std::vector<unsigned char> pixels(const Scene& s) {
  std::vector<unsigned char> out(std::size_t(kW) * kH * 4);
  glGetTextureImage(s.color, 0, GL_RGBA, GL_UNSIGNED_BYTE, GLsizei(out.size()), out.data());
  return out;
}

bool ready(benchmark::State& state, const Scene& s) {
  if (!s.error.empty()) {
    state.SkipWithError(s.error.c_str());
    return false;
  }
  return true;
}

// Args: sprites, lowest and highest height in pixels.
void InstancedQuads(benchmark::State& state) {
  Scene& s = Scene::get();
  if (!ready(state, s)) return;
  const auto sp = sprites(int(state.range(0)), int(state.range(1)), int(state.range(2)));
  double covered = 0;
  for (const Sprite& q : sp) covered += double(q.rect[2] - q.rect[0]) * double(q.rect[3] - q.rect[1]);
  for (auto _ : state) {
    state.PauseTiming();
    clear(s);
    state.ResumeTiming();
    draw_quads(s, sp);
  }
  state.counters["quad_pixels"] = covered;
}

// Args: sprites, lowest and highest height in pixels, tile size T.
void ComputeSplat(benchmark::State& state) {
  Scene& s = Scene::get();
  if (!ready(state, s)) return;
  const int t = int(state.range(3));
  std::string error;
  std::string src = kCs;
  src.insert(src.find('\n') + 1, "#define T " + std::to_string(t) + "\n");
  const GLuint program = link({compile(GL_COMPUTE_SHADER, src, &error)}, &error);
  if (!error.empty()) {
    state.SkipWithError(error.c_str());
    return;
  }
  const auto sp = sprites(int(state.range(0)), int(state.range(1)), int(state.range(2)));
  clear(s);
  draw_quads(s, sp);
  const auto want = pixels(s);
  for (auto _ : state) {
    state.PauseTiming();
    clear(s);
    state.ResumeTiming();
    draw_splat(s, program, t, sp);
  }
  const auto got = pixels(s);
  double se = 0;
  for (std::size_t i = 0; i < got.size(); ++i) se += std::pow(double(got[i]) - double(want[i]), 2);
  state.counters["mse"] = se / double(got.size());
  glDeleteProgram(program);
}

}  // namespace

BENCHMARK(InstancedQuads)->Args({10000, 4, 16})->Args({1000, 4, 16})->Args({50, 300, 400})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(ComputeSplat)
    ->Args({10000, 4, 16, 8})
    ->Args({10000, 4, 16, 16})
    ->Args({1000, 4, 16, 8})
    ->Args({50, 300, 400, 16})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

BENCHMARK_MAIN();
