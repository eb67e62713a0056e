// The GL 4.5 back end: draws a FramePlan into the bound framebuffer of the caller's context.
//  - geometry path: GPU skinning from the model's baked clips (a float texture), one instanced
//    draw per LOD level and primitive for all the characters of the model;
//  - impostor path: the snapshots due are rendered into windows of a 2D-array atlas (one layer per
//    page) with the camera of section 4.2, one instanced draw per LOD level and primitive;
//    then every impostor is one camera-facing quad of one instanced draw (sorted back to front
//    when blended, see ImpostorEdges).
// Shading is the same in both paths (base colour x texture, one directional light in world space),
// so a snapshot matches the geometry it replaces. Needs a current OpenGL 4.5 core context; all
// methods must be called with that context current. No GL type appears in this header.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "bb/result.h"
#include "bb/runtime/crowd.h"
#include "bb/runtime/model.h"

namespace bb::runtime {

// How an impostor quad's edges meet the framebuffer. The window holds the snapshot at about 2
// texels per pixel (ImpostorConfig::texels_per_pixel), premultiplied, alpha = coverage. Measured
// on the flow test bed (20 humans of 50-100 px, every impostor refreshed, 4x MSAA, llvmpipe),
// PSNR against the geometry frame / impostor time over geometry time: kBlend 29.9 dB / 0.83-0.92,
// kSamples 29.5 dB / 1.03-1.10, kAlphaToCoverage 28.0 dB / 0.87, kAlphaTest 23.3 dB / 0.91.
enum class ImpostorEdges {
  // Four taps at the standard 4x sample positions average the pixel's footprint (alpha = its
  // coverage); premultiplied blending, the quads sorted back to front by the renderer. Soft
  // edges in any framebuffer; two impostors that cross each other blend in one order only. In a
  // multisampled framebuffer the quads are rasterized single-sampled (GL_MULTISAMPLE off for the
  // pass, then restored): the taps already give the edge, so per-sample coverage only costs
  // (flow test bed, 4x MSAA, llvmpipe: the same frames, part cards 10-20 % faster, whole
  // impostors 3-6 %, and then faster than kAlphaToCoverage with +2.4 dB when every one is fresh).
  kBlend,
  // Multisampled framebuffer: each sample of the pixel looks the window up at its own position
  // and is covered when that point is at least half covered, so the edges are antialiased the way
  // the geometry's are, in any order and with the depth test. Single-sampled: the alpha test.
  kSamples,
  // The four-tap coverage picks that share of the pixel's samples (quantized, fixed pattern).
  kAlphaToCoverage,
  kAlphaTest,  // the four-tap coverage >= 0.5 (hard edges)
  // One tap at the pixel centre, alpha tested: an exact copy of the snapshot when its texels lie on
  // the pixels (render_portrait's one texel per pixel); aliased at any other scale.
  kCentre,
};

// Samples per pixel that a target holding only impostors (RenderMode::kImpostor, nothing else
// drawn) needs for the picture a `scene_samples` target would give: 1 for kBlend, whose quads are
// rasterized single-sampled, so every sample of a pixel holds the same colour and the resolved
// frame is the same to the bit; `scene_samples` for the others, which write a share of the samples
// (the alpha-tested modes too: the quads' own edges are multisampled, the frames differ by
// ~0.001 dB). On llvmpipe a 4x target makes a blended impostor pixel read and write four samples
// (flow test bed, 17 degrees: the impostor frame 25-30 % faster single-sampled, the Fox and ours).
int impostor_target_samples(ImpostorEdges edges, int scene_samples);

// Whether the current GL context renders in software (Mesa's llvmpipe or softpipe), where fill and
// multisampling cost far more than on a GPU and the cheaper choice between a snapshot and geometry
// differs (flow's `auto` settings). False without a current context.
bool software_rasterizer();

struct DrawOptions {
  bool draw_geometry = true;
  bool draw_impostors = true;
  bool take_snapshots = true;
  ImpostorEdges edges = ImpostorEdges::kBlend;
  // Records GPU timestamps between the stages of draw() (Renderer::stage_times): for profiling;
  // costs a few queries per frame. On llvmpipe each timestamp makes it finish the stage before it,
  // which changes what is measured (flow test bed, four bodies against one: 0.3 ms more with the
  // stamps, 0.1 ms without); judge a change there by frame times taken without them.
  bool time_stages = false;
  // Flushes the commands to the GPU after every this many indices of a pass (the geometry, or the
  // snapshots), splitting instanced draws where needed; the frames are the same to the bit.
  // -1: auto; 0: never; N: every N indices, into any target. Mesa's llvmpipe shades a draw's
  // vertices on the thread that submits it and rasterizes only from a flush on, so without
  // flushes a frame's vertex work and its rasterization run one after the other. Auto flushes
  // every kSoftwareFlushIndices on a software rasterizer, into a single-sampled target, in a
  // geometry pass of twice that and more, or a snapshot pass of six times that (it ends in a
  // framebuffer change, which flushes anyway); never on a GPU. Flow test bed, 20 humans, geometry frames at one
  // sample: our four bodies 7.3 -> 5.4 ms, CesiumMan 18.8 -> 11.2 ms, the Fox 5.3-5.8 -> 5.2 ms;
  // 10,000 of our bodies 590 -> 550 ms, and their impostors with 1,000 refreshes a frame 108 ->
  // 90 ms. Into a multisampled target flushes cost more than they overlap (our bodies at 4
  // samples 14.3 -> 17.1 ms, 10,000 of them 1.36 -> 1.9 s), and in short passes they leave no
  // vertex work to overlap.
  int flush_every_indices = -1;
};

// DrawOptions::flush_every_indices's auto value on a software rasterizer (llvmpipe): indices.
inline constexpr int kSoftwareFlushIndices = 10000;

// GPU time of each stage of the last draw() made with DrawOptions::time_stages, ms (timestamps
// taken on the GPU between the stages, so each covers its stage's commands as the GPU ran them).
struct StageTimes {
  double snapshots = 0;  // clearing and drawing the due snapshots into the atlas (and resolving them)
  double coverage = 0;   // the compute pass fitting the quads to the new snapshots' coverage
  double geometry = 0;   // the characters drawn as skinned geometry
  double impostors = 0;  // the impostor quads
  bool valid = false;    // false: the last draw did not time its stages
};

class Renderer {
 public:
  // Uploads the model (meshes, textures, baked clips) and creates the atlas (config.page_size
  // squared, config.atlas_pages layers (0: config.max_pages), RGBA8 + one shared depth buffer);
  // a config that breaks a contract (validate_impostor_config: a page smaller than the largest
  // window, no page, a window of no pixel, ...) returns that error, naming the setting,
  // or draws into `share_atlas`'s (not null: made for the same page size, pages, smallest window
  // and kind of snapshots; it may be destroyed first, the atlas living as long as a renderer
  // draws into it). The planner that makes the plans must use the same config (windows, page
  // size, pages, first_page). Renderers of several models sharing one atlas, each with
  // shared_atlas_config(config, k, n), let draw_many draw all their blended quads in one draw.
  // The atlas's pictures are those of the plans this renderer drew: a planner whose plans another
  // renderer drew needs FramePlanner::invalidate() before this one draws its plans
  // (holds_snapshots_for; without it, one frame of that planner's impostors is drawn from empty
  // windows and the planner then takes them all anew: FramePlan::drawn_from_another_atlas).
  static Result<std::unique_ptr<Renderer>> create(const Model& model, const ImpostorConfig& config = {},
                                                  const Renderer* share_atlas = nullptr);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  // Draws one frame into the currently bound draw framebuffer, with the plan's camera viewport
  // (0, 0, width, height). Does not clear it. Snapshots first (they change the atlas), then
  // geometry, then impostors. `plan` must come from a FramePlanner of the same model and config,
  // whose earlier plans this renderer drew (holds_snapshots_for; where not, the plan is marked and
  // its planner starts over at its next frame).
  // GL state left changed: program 0, VAO 0, the textures bound to units 0-6 (no sampler objects
  // left bound), viewport, depth test on (LESS, writes on), blending, alpha to coverage and face
  // culling off, the cull face GL_BACK and the front face GL_CCW (multisampling as found). Back
  // faces of materials that are not double-sided (glTF's default) are culled in the scene's
  // geometry and in the snapshots.
  // The snapshot passes into the atlas do not take the game's scissor test, polygon offset,
  // polygon mode, rasterizer discard, colour masks or (multisampled snapshots) sample masking:
  // each is turned off there and put back as found, with the draw framebuffer, the viewport and
  // the clip distances 0-3. The game's scissor rectangle, polygon offset and masks still apply to
  // the geometry and the impostor quads, drawn into its framebuffer.
  void draw(const FramePlan& plan, const DrawOptions& options = {});
  // One frame of several models' crowds (renderers[k] draws plans[k], planned with one camera,
  // e.g. by FramePlanner::plan_many), as draw() would each, but by stage: every renderer's
  // snapshots, then every renderer's geometry, then the impostors. Blended impostors
  // (ImpostorEdges::kBlend) of different models that overlap on screen are then drawn back to front
  // across the models, not model after model. Renderers sharing one atlas (create's share_atlas)
  // with alike programs draw every quad in one sorted draw (flow test bed on an H200, our four
  // bodies: 1,000 humans 3.1-3.5x against 2.1-2.3x with an atlas each; the same pictures). Else
  // each model's quads are sorted into layers
  // (kMaxImpostorLayers at most) so that of two overlapping quads of different models the farther
  // is drawn in an earlier layer, and each layer is a draw per model. (Model after model, a nearer
  // quad drawn first hides the farther quad of the next model under its soft edge, whole impostors
  // writing depth there; part cards, which write none, are wholly painted over. Flow test bed, our
  // four bodies, every impostor fresh: 26.73 -> 27.10 dB; part cards at 8 degrees, 25.59 -> 25.83
  // dB.) With DrawOptions::time_stages each renderer draws its whole frame in turn instead, so that
  // its stage times are its own.
  static void draw_many(std::span<Renderer* const> renderers, std::span<const FramePlan* const> plans,
                        const DrawOptions& options = {});
  static constexpr int kMaxImpostorLayers = 8;
  // Whether this renderer's atlas holds the snapshots `plan` draws from earlier plans: true when the
  // plan needs none (FramePlan::cache_plans_before 0: a new planner's or one just invalidated) or
  // when this renderer took the last snapshots of the plan's cache. False for a renderer made anew
  // (or another one) drawing an existing planner's plans: its quads would show empty windows. Call
  // FramePlanner::invalidate() first.
  bool holds_snapshots_for(const FramePlan& plan) const;
  // The directional light (world, towards the light; normalised here; default (0.4, 0.8, 0.6)).
  // Geometry and new snapshots take it at once; impostors already in the atlas keep the light
  // they were taken under unless the renderer relights them (ImpostorConfig::relight).
  void set_light(glm::vec3 towards_light);

  // Copies page `page` of the atlas (numbered as the plans number them, from ImpostorConfig::
  // first_page in a shared atlas; RGBA8, premultiplied, rows bottom to top) for inspection.
  std::vector<std::uint8_t> read_atlas_page(int page) const;
  // The rectangle (window units: x0, y0, x1, y1) that the last snapshot in the window of coverage
  // slot `slot` (BillboardGpu::layer.y) covers, widened by its taps' reach, as found on the GPU
  // (ImpostorConfig::fit_quads_to_coverage); x0 > x1 when nothing is covered. For inspection.
  glm::vec4 coverage_rect(int slot) const;
  // Invocations per side of the coverage pass's work groups (ImpostorConfig::coverage_group as
  // resolved for this GL: 4, 8 or 16).
  int coverage_group() const;
  // Whether the impostor quads are pulled by the vertex shader (ImpostorConfig::quad_fetch as
  // resolved for this GL) rather than drawn as instances.
  bool pulls_quads() const;
  // Window texels under the impostor quads of `plan` as drawn: the planner's quads
  // (FrameStats::quad_texels), narrowed to the coverage rectangles where they are fitted. Reads
  // the rectangles back from the GPU (waits for it): for reports, outside timed frames.
  double drawn_quad_texels(const FramePlan& plan) const;
  // The stage times of the last draw() with DrawOptions::time_stages (waits for the GPU to reach
  // its end): for reports, outside timed frames.
  StageTimes stage_times() const;
  const Model& model() const;

 private:
  Renderer();
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// An offscreen framebuffer (RGBA8 colour + 24-bit depth) to render into headless; `samples` > 1
// makes it multisampled (read_rgba resolves it), clamped to GL_MAX_SAMPLES; samples() is what the
// driver gave, which may be more than asked.
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
  int samples() const { return samples_; }

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
