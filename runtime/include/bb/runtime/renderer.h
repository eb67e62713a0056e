// The GL 4.5 back end: draws a FramePlan into the bound framebuffer of the caller's context.
//  - geometry path: GPU skinning from the model's baked clips (a float texture), one instanced
//    draw per LOD level and primitive for all the characters of the model;
//  - impostor path: the snapshots due are rendered into windows of a 2D-array atlas (one layer per
//    page) with the camera of section 4.2, one instanced draw per LOD level and primitive;
//    then every impostor is one camera-facing quad of one instanced draw.
// Shading is the same in both paths (base colour x texture, one directional light in world space),
// so a snapshot matches the geometry it replaces. Needs a current OpenGL 4.5 core context; all
// methods must be called with that context current. No GL type appears in this header.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "bb/result.h"
#include "bb/runtime/crowd.h"
#include "bb/runtime/model.h"

namespace bb::runtime {

struct DrawOptions {
  bool draw_geometry = true;
  bool draw_impostors = true;
  bool take_snapshots = true;
  // Impostor quads: alpha-tested at 0.5 (default, order independent) or premultiplied blending
  // (soft edges; best with back-to-front order).
  bool blend_impostors = false;
  // Impostor quads into a multisampled framebuffer (and blend_impostors off): the coverage of the
  // pixel in the window (alpha, averaged over four taps) chooses the share of the pixel's samples
  // the quad covers, so edges come out antialiased like multisampled geometry, in any order and
  // with the depth test. Into a single-sampled framebuffer the alpha test at 0.5 is used.
  bool alpha_to_coverage = true;
};

class Renderer {
 public:
  // Uploads the model (meshes, textures, baked clips) and creates the atlas (config.page_size
  // squared, config.max_pages layers, RGBA8 + one shared depth buffer). The planner that makes
  // the plans must use the same config (windows, page size, pages).
  static Result<std::unique_ptr<Renderer>> create(const Model& model, const ImpostorConfig& config = {});
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  // Draws one frame into the currently bound draw framebuffer, with the plan's camera viewport
  // (0, 0, width, height). Does not clear it. Snapshots first (they change the atlas), then
  // geometry, then impostors. `plan` must come from a FramePlanner of the same model and config.
  // GL state left changed: program 0, VAO 0, texture units 0-3, viewport, depth test on (LESS,
  // writes on), blending, alpha to coverage and face culling off.
  void draw(const FramePlan& plan, const DrawOptions& options = {});

  // Copies page `page` of the atlas (RGBA8, premultiplied, rows bottom to top) for inspection.
  std::vector<std::uint8_t> read_atlas_page(int page) const;
  const Model& model() const;

 private:
  Renderer();
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// An offscreen framebuffer (RGBA8 colour + 24-bit depth) to render into headless; `samples` > 1
// makes it multisampled (read_rgba resolves it).
class OffscreenTarget {
 public:
  static Result<std::unique_ptr<OffscreenTarget>> create(int width, int height, int samples = 1);
  ~OffscreenTarget();
  OffscreenTarget(const OffscreenTarget&) = delete;
  OffscreenTarget& operator=(const OffscreenTarget&) = delete;
  // Binds it for drawing, sets the viewport, and clears to transparent black when `clear`.
  void bind(bool clear = true);
  // RGBA8 pixels, rows top to bottom (as PNG wants); waits for the GPU.
  std::vector<std::uint8_t> read_rgba() const;
  int width() const { return width_; }
  int height() const { return height_; }

 private:
  OffscreenTarget() = default;
  int width_ = 0, height_ = 0, samples_ = 1;
  unsigned fbo_ = 0, color_ = 0, depth_ = 0;
  unsigned resolve_fbo_ = 0, resolve_color_ = 0;
};

// GPU time of the commands between begin() and end() (GL_TIME_ELAPSED query); elapsed_ms waits
// for the result. Use finish() around a frame for the wall time to completion instead.
class GpuTimer {
 public:
  GpuTimer();
  ~GpuTimer();
  GpuTimer(const GpuTimer&) = delete;
  GpuTimer& operator=(const GpuTimer&) = delete;
  void begin();
  void end();
  double elapsed_ms();

 private:
  unsigned query_ = 0;
};

// glFinish(): returns when every command issued so far has completed.
void gpu_finish();

}  // namespace bb::runtime
