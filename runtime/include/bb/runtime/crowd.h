// Characters of one model and the per-frame decisions (no GL): animation time, culling, geometry
// LOD or impostor window, the two cache tests, atlas windows. The GL Renderer draws a FramePlan.
// After the first frames the planner allocates nothing (nor when characters come and go, once its
// crowd has been as large).
#pragma once

#include <array>
#include <cassert>
#include <cstdint>
#include <memory>
#include <span>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "bb/runtime/impostor.h"
#include "bb/runtime/model.h"

namespace bb::runtime {

// One character: where it stands and what it plays. Its local clip time at scene time t is
// clip_time(phase + speed * t, duration, loop = true).
struct Character {
  glm::vec3 position{0.0f};  // world, metres (the model's origin goes here)
  float yaw = 0.0f;          // radians about +Y; 0 faces +Z
  float scale = 1.0f;        // uniform; may change between frames (an impostor's quad scales with it)
  int clip = 0;              // index into Model::clips (ignored when the model has none)
  float phase = 0.0f;        // seconds added to the scene time
  float speed = 1.0f;        // playback rate
  // Who this is to the impostor cache: a FramePlanner keeps a character's snapshots with its id, so
  // removing, reordering or replacing characters (Crowd::remove, or characters() edited at will)
  // between frames leaves each with its own picture. Crowd::add gives a character without one (0)
  // the next of the crowd's ids, or keeps the game's own (an entity's: then a crowd rebuilt every
  // frame in any order keeps its snapshots). Ids should be unique in a crowd: a copy of a
  // character keeps its id, so set id = 0 to add it as another. 0 in characters() (put there
  // directly): known by its index alone, as if its snapshot were the index's (the character now
  // there keeps it until a cache test fires).
  std::uint32_t id = 0;
};

class Crowd {
 public:
  explicit Crowd(const Model& model) : model_(&model) {}
  const Model& model() const { return *model_; }
  // Appends `c`, under the crowd's next id if c.id is 0 (Character::id); returns its index.
  int add(const Character& c) {
    characters_.push_back(c);
    if (c.id == 0) {
      characters_.back().id = next_id_++;
      if (next_id_ == 0) next_id_ = 1;
    }
    return static_cast<int>(characters_.size()) - 1;
  }
  // Removes character i (< size()) in constant time: the last character takes its index (the order
  // of the others is not kept; to keep it, erase from characters()). Its impostor windows go back to
  // the atlas at the next frame planned.
  void remove(std::size_t i) {
    assert(i < characters_.size());
    if (i + 1 < characters_.size()) characters_[i] = characters_.back();
    characters_.pop_back();
  }
  void reserve(std::size_t n) { characters_.reserve(n); }
  // Removes every character and starts the ids over, so that a crowd rebuilt every frame with add()
  // in the same order gets the same ids (give ids of your own to rebuild it in any order).
  void clear() {
    characters_.clear();
    next_id_ = 1;
  }
  std::size_t size() const { return characters_.size(); }
  Character& operator[](std::size_t i) { return characters_[i]; }
  const Character& operator[](std::size_t i) const { return characters_[i]; }
  std::vector<Character>& characters() { return characters_; }
  const std::vector<Character>& characters() const { return characters_; }

 private:
  const Model* model_;
  std::vector<Character> characters_;
  std::uint32_t next_id_ = 1;
};

// World position of the character's Ta at scene time `time` (section 4.2's fixed point, carried
// by the clip's root travel): where its impostor is centred, a good camera target.
glm::vec3 character_ta(const Model& model, const Character& character, float time);

enum class RenderMode {
  kGeometry,  // every visible character as skinned geometry (the baseline)
  kImpostor,  // every visible character as an impostor
  kAuto,      // impostors, but characters bigger on screen than the switch size stay geometry
};

struct ImpostorConfig {
  WindowSizes windows;            // 256, 128, 64, 32 (section 4.3), 16, 8 by default
  int page_size = 1024;           // atlas page, pixels (square)
  int max_pages = 32;             // when all are full, characters fall back to geometry
  // An atlas shared by several models (shared_atlas_config; the renderers made with
  // Renderer::create's `share_atlas`): this model's pages are [first_page, first_page + max_pages)
  // of an atlas of atlas_pages pages. Renderer::draw_many then draws every model's blended quads
  // in one back-to-front draw, where models of atlases of their own take a draw per model and per
  // layer of overlaps. 0, 0: an atlas of the model's own.
  int first_page = 0;
  int atlas_pages = 0;  // 0: max_pages
  CacheConfig cache;              // section 5
  // kAuto: a character whose on-screen diameter exceeds windows.size[0] * geometry_switch
  // pixels stays geometry (1.0: where a texel of the largest window would cover a pixel).
  float geometry_switch = 1.0f;
  float snapshot_distance = 0.0f; // D of section 4.2 (orthographic); <= 0: 2 * radius
  // Clear and draw only the part of each window the pose covers instead of the whole square:
  // less fill for the snapshot and the quad. The part is the pose's box projected on the snapshot
  // plane, narrowed to the union of the body parts' boxes (Model::body_parts), each carried by its
  // bone: a 3D box's depth widens its picture, and a limb's box lies along the limb. Flow test bed
  // (20 humans, 1280x1024): 223k quad texels per frame instead of 277k, same PSNR to 0.01 dB.
  bool tight_quads = true;
  // Texels per screen pixel wanted when choosing the window (section 4.3 uses 1). 2 (default)
  // supersamples the snapshot: the impostor shader's taps over each pixel see its coverage, so
  // the edges come out like multisampled geometry (flow test bed, 20 humans of 50-100 px, 4x
  // MSAA, llvmpipe: every impostor refreshed 30.5 dB against the geometry frame instead of 27.8
  // at 1; 4x the atlas texels; at the view threshold 8 degrees 4.0-4.3x faster than geometry
  // instead of ~5x at 1).
  float texels_per_pixel = 2.0f;
  // Perspective snapshots from the eye (exact when taken) or the paper's orthographic ones.
  bool perspective_snapshots = true;
  // Perspective snapshots only: widen the frustum so the snapshot has texels_per_pixel texels per
  // screen pixel at Ta (on the view axis) when the window is larger than that needs: the character
  // then uses part of its window instead of filling it (1-2x texels_per_pixel per axis with
  // power-of-two windows), so a refresh draws fewer texels. Flow test bed (20 humans, 1 texel per
  // pixel, 4x MSAA, llvmpipe, 30 frames), whole impostors: faster at every threshold (worst case
  // 1.22x -> 1.38x geometry's speed, posture 0.1 2.04x -> 2.36x, 8 degrees 5.01x -> 5.06x), PSNR
  // -1.4 dB with every impostor refreshed, -0.5 dB at posture 0.05, the same (+-0.1 dB) from
  // posture 0.1 and 1 degree up; the Fox's worst case 1.33 -> 1.09 of geometry's time. Part cards
  // at 8 degrees: 2.69x -> 2.88x but 24.41 -> 23.20 dB (small cards lose the supersampling).
  // Off by default here; `bodybuilder flow` turns it on for whole impostors.
  bool texel_per_pixel = false;
  // Snapshots on the screen's pixel grid (make_aligned_snapshot_camera): the snapshot is cut out
  // of the scene camera's own image, its window centred on a pixel corner, texels_per_pixel
  // texels to a pixel, and drawn on a plane parallel to the screen (whole impostors: through Ta,
  // turned with the camera; part cards: carried by the bone). A fresh impostor is then the
  // geometry's picture, not a resampled one. Characters too close or too big for the largest
  // window at that scale fall back to the snapshot camera of section 4.2.
  // With snapshot_samples 4, texels_per_pixel 1 and ImpostorEdges::kBlend, flow test bed (20
  // humans, 4x MSAA, llvmpipe), every impostor refreshed: 49.2 dB against the geometry frame
  // (SSIM 1.000) instead of 31.7 (2 texels, blend) or 26.1 (1 texel, alpha to coverage), but
  // 0.81x the geometry's speed instead of 1.07-1.44x (a multisampled snapshot costs what the
  // geometry does). Between refreshes it gains little: at 8 degrees whole impostors 12.8 against
  // 12.5 dB, part cards 25.4 against 25.3 dB. Off by default.
  bool aligned_snapshots = false;
  // With aligned_snapshots: how far (pixels, both axes, 0 <= phase < 1) the texel grid sits right
  // of and above the pixel grid when a snapshot is taken (make_aligned_snapshot_camera's phase).
  // 0: a fresh snapshot's texels on the pixels (exact with snapshot_samples 4, or with one tap in
  // a single-sampled scene). 1/8 with one tap (impostor_taps 1) in a 4x multisampled scene: the
  // bilinear tap then mixes each texel with a sixteenth of its neighbours to the left and below
  // (weights 49, 7, 7, 1 of 64), an edge softened about as much as the scene's four samples soften
  // it. Flow test bed, 20 humans, 4x MSAA, one texel per pixel, every impostor fresh, PSNR over
  // the geometry's pixels (fortieth session): one tap on the pixel grid 25.86 dB; phase 1/16, 1/8,
  // 3/16 27.02, 27.74, 27.80 dB (CesiumMan 23.63, 23.65, 23.28); -1/8 27.28 dB; two taps on
  // the free grid (the earlier default) 26.72 dB, CesiumMan 22.34. Between refreshes the
  // character has moved off the grid and one tap is one tap anywhere (-0.1 dB against two).
  float aligned_phase = 0.0f;
  // Quads fitted to the coverage: after each snapshot the GPU finds the rectangle of the window
  // that its covered texels fill (plus two texels for the filter taps), and the impostor's quad
  // shrinks to it. The planner's quad comes from boxes (the pose's, the body parts'), which are
  // loose: a box's picture is wider than the limb in it. One quad still, so no extra triangles;
  // FrameStats::quad_texels still counts the planner's quads. Flow test bed (llvmpipe, alternating
  // pairs): impostor frame time -3 % at 8 degrees and -16 % at 17 on our humans, -16 % on the Fox
  // (2.2x -> 2.7x at 8 degrees); same frames to one level. The pass reads every texel of the new
  // snapshots' quads, which pays back only over the frames a snapshot is drawn again, so a snapshot
  // replacing one that lived a single impostor frame keeps the box (FramePlanner::fit_quad). Every
  // impostor refreshed every frame, 20 humans: 1.67-1.74x -> 1.81-1.82x the geometry's speed at 4x
  // MSAA, 1.32-1.43 -> 1.18-1.19 times its frame time at one sample; part cards at 8 degrees draw
  // 1.8 % more quad texels (within the timing noise).
  bool fit_quads_to_coverage = true;
  // With fit_quads_to_coverage, the quads are fitted on the CPU instead: the planner skins the
  // snapshot level's vertices (a part card's: its triangles') as the snapshot shader does and
  // projects them with the snapshot camera; their extent, widened by the taps' reach, bounds every
  // texel the snapshot covers, so the pictures are the same, and a frame needs no coverage pass (a
  // dispatch and a barrier, which llvmpipe carries out as a finish; depth-corrected cards still
  // take it for their wide offsets). Flow test bed on llvmpipe (thirty-eighth session, alternated
  // runs): whole impostors the same within the noise (main run 1.93-2.02 against 1.97-2.00 ms,
  // planning +0.04 ms for our four bodies; RiggedSimple orbiting at 17 degrees 3.9-4.9x against
  // 3.8-4.4x), 5 % more quad texels (vertices lie up to a texel past the texel centres they cover);
  // part cards at 8 degrees 4.62-4.65 against 4.81-4.91 ms (planning +0.17 ms, 7 % more quad
  // texels), 25.828 against 25.830 dB; with one atlas for the four bodies (thirty-ninth session)
  // part cards 11 % faster. Off by default: the fit costs CPU time per vertex, about 24 us a
  // CesiumMan snapshot (bench_runtime: 10,000 walking, 9.5 % refreshed, planning 22.8 against 1.0
  // ms a frame; 1,000 with part cards 4.2 against 1.4 ms), the pass GPU time per texel. On the
  // H200, where the pass is 0.02 ms, the fit's planning made the frame slower (20 humans 0.62-0.69x
  // against 0.76x, part cards 0.22x against 0.27-0.28x); the flow test bed takes it on a software
  // rasterizer only (--quad-fit auto).
  bool fit_quads_from_vertices = false;
  // Invocations per side of the coverage pass's work groups (one group per new snapshot; 4, 8 or
  // 16; 0: 4 on a software rasterizer, 16 on a GPU). Each invocation walks its share of the
  // window's texels one gather of 2x2 at a time, so on a GPU that walk is what a snapshot's group
  // waits for: a 128-texel window takes 256 steps with 4x4 invocations, 16 with 16x16. The H200
  // gave the pass 0.07 ms of GPU time for the snapshot or two of the paper's 20 humans (thirty-
  // fourth session), which such a walk explains; 16x16 there is not measured yet
  // (bench/flow/gpu_run.sh s35). llvmpipe runs a group's invocations as one thread's SIMD lanes:
  // 16x16 gives the same times within the noise there (part cards at 8 degrees, ~50 new snapshots
  // a frame: impostor frame 4.79-5.45 against 4.67-5.63 ms, three alternated runs), and 4x4 stays.
  // The rectangles are the same whatever the size (a minimum and maximum over the same texels).
  int coverage_group = 0;
  // How the impostor quads reach the vertex shader (0: auto, pulled on a software rasterizer and
  // instanced on a GPU; 1: instanced; 2: pulled). Instanced: an instance of four vertices per quad,
  // its BillboardGpu as per-instance attributes. Pulled: one indexed draw of six indices per quad,
  // the vertex shader fetching its BillboardGpu from a buffer texture by gl_VertexID / 4 (up to
  // GL_MAX_TEXTURE_BUFFER_SIZE / 7 quads: Renderer::create refuses 2 where 4 million do not fit,
  // and auto then instances). The same vertices and pictures either way
  // (CrowdRender.PulledQuadsDrawWhatInstancedQuadsDraw). llvmpipe runs its vertex pipeline once per
  // instance, which four vertices cannot amortise: flow test bed, 10,000 RiggedSimples, the impostor
  // frame's submission 6.5-8.3 -> 3.6-4.4 ms and the speed-up 4.6-4.9x -> 5.3-5.9x; 10,000 of the
  // default crowd 59.6-60.3x -> 65.2-69.0x (three alternated runs each, fifty-third session); the
  // paper's 20 humans the same. A GPU runs instances of four vertices well; not measured there.
  int quad_fetch = 0;
  // Samples per texel of the snapshots (1 or 4). 4: drawn multisampled into a scratch page and
  // resolved into the atlas, so alpha holds each texel's coverage as the geometry's multisampled
  // pixels do; the impostor shader then takes one tap per pixel. 1: single-sampled, the impostor
  // shader takes impostor_taps taps per pixel (four: at the 4x sample positions, for the coverage).
  int snapshot_samples = 1;
  // Taps of the impostor shader per pixel, with snapshot_samples 1 (4, 2 or 1). 4: at the 4x sample
  // pattern, averaged: the pixel's coverage as a multisampled scene's pixel has it. 1: one
  // bilinear tap at the pixel's centre, for a single-sampled scene, whose pixels hold no coverage
  // to match. Flow test bed (20 humans, llvmpipe, one sample): one tap is 1.05 times the
  // geometry's frame time with every impostor refreshed (four: 1.18), 4.9x against 3.7x at 8
  // degrees, for 0.2-0.3 dB; at 4x MSAA four taps keep 0.3 dB on whole impostors and 0.75 dB on
  // part cards.
  // 2: two bilinear taps 0.2 pixels out on the anti-diagonal, averaged: nearly the coverage of four
  // at one texel per pixel, for half the fetches. Flow test bed (4x MSAA, 1 texel per pixel, 30
  // frames, twenty-third session), whole impostors against four taps: every impostor fresh -0.03 dB
  // on our crowd (Fox -0.17, RiggedSimple -0.14, CesiumMan +0.02), 8 and 17 degrees -0.07 to -0.15
  // dB, and the impostor frame 5-25 % shorter (the Fox at 17 degrees 4.8x -> 6.3x geometry's speed);
  // part cards at 8 degrees -0.2 to -0.33 dB; at 2 texels per pixel the taps skip texels (-0.4 dB).
  // 0 and below count as 1, other values as 4.
  int impostor_taps = 4;
  // The snapshot's mesh LOD: the level the geometry path would draw for the character at its
  // size on screen now (true: the impostor shows the same silhouette as the geometry it
  // replaces), or the level that matches the window size (false: section 4.3 literally; finer,
  // so costlier, when the window is larger than the character).
  bool snapshot_lod_from_screen = true;
  // Part cards (the paper's section 7, item 2): each body part of Model::body_parts (our body:
  // pelvis, chest+head, thighs, shins, feet, upper arms, forearms+hands) gets its own snapshot of
  // its own triangles, in its own window, drawn as its own card with depth. The card is the plane
  // through the part's centre facing the eye at snapshot time; until the next snapshot it is
  // carried by the part's bone (current bone matrix x inverse of the one at snapshot time), so the
  // limbs keep following the animation and the character's turning, and the depth test orders
  // the parts. The view test is per part: the angle between the card's carried normal and the
  // line of sight (its tilt; a roll about the line of sight is reproduced exactly), against
  // cache.view_threshold_deg; the posture test stays per character (all its parts). FrameStats::
  // refresh_fraction then counts cards. A model with one part draws ordinary impostors.
  // Flow test bed (20 humans, 1280x1024, llvmpipe, posture off, view 8 degrees): PSNR against
  // geometry 24.0 dB instead of 12.6 (SSIM 0.91 instead of 0.42), 20 % of the cards refreshed
  // per frame instead of 5 % of the impostors, impostor/geometry time 0.32 instead of 0.19; with
  // 2 texels per pixel + blending 26.0 dB (SSIM 0.95) at 0.60 instead of 12.5 dB at 0.22. At 5
  // degrees 24.8 / 27.7 dB, at 17 degrees 21.6 / 22.4 dB. Every card fresh: 25.8 dB (whole
  // impostors 26.2; 30.4 against 31.7 with 2 texels + blending). Off by default: far better
  // quality between refreshes, but short of 28 dB at 8 degrees and slower.
  bool part_cards = false;
  // Part cards take no window smaller than this (pixels): a small part keeps the texels it had
  // in the paper's smallest window. Flow test bed, part cards at 8 degrees, posture off, 30
  // frames: 25.59 dB in 8 atlas pages with 32, 25.54 dB in 12 pages with windows down to 8, and
  // no faster (impostor frame 5.0-5.1 against 5.2-5.4 ms).
  int smallest_part_window = 32;
  // Part cards of limbs (BodyPart::elongation >= kLimbElongation, flatness <= kLimbFlatness:
  // thighs, shins, feet, upper arms, forearms on our body) turn about the limb's axis to face the
  // eye between snapshots, as a cylinder looks the same turned about its axis; their view test is
  // then the change of the angle between that axis and the line of sight. Off by default: on the
  // flow test bed (20 humans, 8 degrees, posture off, llvmpipe) it refreshes 23 % fewer cards and
  // draws 18 % fewer snapshot triangles, but the frame time is the same (the cards' fill dominates)
  // and PSNR is 0.34 dB lower (23.57 against 23.91); with the poses held it is 0.4 dB higher.
  bool turn_limb_cards = false;
  // Threads that plan a frame (FramePlanner::plan), the calling thread included; 0: one per
  // hardware thread. Crowds of at least FramePlanner::kParallelCharacters units of work (a
  // character is one, or one a card with part cards, and each impostor the last frame refreshed
  // kRefreshWork more) are planned in chunks on a pool of worker threads (started once, asleep between frames); the
  // plan is the same whatever the number of threads. 1: on the calling thread only.
  unsigned planner_threads = 0;
  // Depth-corrected part cards (parallax): each card also carries its snapshot's eye (in the
  // card's frame) and the snapshot pass also writes each texel's offset from the card plane
  // (half sizes, masked by coverage: RG16F pages beside the atlas), so a pixel looks up the
  // texel whose stored surface point lies on its own eye ray (iterative parallax mapping from the
  // card plane, a few steps, one bilinear fetch each) instead of the texel where the ray meets
  // the plane. Where no covered texel is near, the first step takes the offsets' 4x4 means
  // (written by the coverage pass), so silhouettes move with their surface (within the quad
  // fitted to the coverage: widening it by the depth range's shift cost 14 % of the card pass for
  // no measured gain). Perspective snapshots with one sample, on a renderer with layered
  // snapshots only (else ignored). Fifteenth session, flow test bed, 8 degrees, 30 frames: the
  // card pass 4.8 -> 2.6 ms against the depth gathers it replaced, same PSNR; 2 texels per pixel,
  // blended, depth pass: 28.13 dB at 1.6x (was 1.3x).
  // Flow test bed (20 humans, posture off, llvmpipe), 2 texels per pixel + blending, walking:
  // 8 degrees 25.87 -> 27.57 dB (1.90x -> 1.31x geometry's speed), 5 degrees 27.48 -> 28.48 dB
  // (1.58x -> 1.06x); poses held, 8 degrees 25.31 -> 27.73 dB (sixth session). With leading
  // cards and the quads no longer widened, 120 frames: 8 degrees 27.73 dB at 1.43x, 28.10 dB at
  // 1.05x with parallax_depth_pass. Off by default: slower on llvmpipe, where cards are fill.
  bool parallax_cards = false;
  int parallax_steps = 2;  // fixed-point steps per pixel (flow test bed: 1 step 27.54 dB, 2 27.73, 3 27.72)
  // Depth-corrected cards write the depth of the surface they show, so with alpha-to-coverage
  // edges overlapping cards (at the joints) hide each other per pixel. Blended cards write no
  // depth (a soft edge would hide the card behind it); with parallax_depth_pass they are drawn
  // twice: the opaque texels' depth first, then the colours, blended where they are not behind
  // it. Flow test bed, 120 frames, walking, 8 degrees, 2 texels per pixel, blended, leading
  // cards: 27.73 -> 28.10 dB (interior squared error 60 -> 48), but the second pass over every
  // card costs about a quarter of the impostor frame on llvmpipe (30 frames, fifteenth session:
  // 2.13x -> 1.63x geometry's speed).
  bool parallax_depth_pass = false;
  // Relit snapshots: a snapshot stores the albedo and, in a second atlas of the same pages, the
  // normal in the snapshot camera's frame; the impostor shader lights them with the normals turned
  // into the quad's frame of the moment (a part card's axes as its bone carries them, a whole
  // impostor's as it faces the eye). A part card turned by its bone since its snapshot is then
  // shaded as it now lies under the light instead of as it lay (same diffuse model as the
  // geometry), and impostors follow a light that moves (Renderer::set_light) without new snapshots.
  // Doubles the atlas memory (RGBA8 normals). On a renderer with layered snapshots
  // and one sample per texel only (else ignored).
  bool relight = false;
  // Leading part cards: a card's snapshot is taken along the mean of its part's line of sight
  // (in the bone's frame) over the time the card will last, found by playing the clip on and
  // carrying the eye on at its velocity in the character's frame until the line of sight has
  // turned by the view threshold, instead of along the line of sight of the moment. Between
  // refreshes the card is then seen from both sides of its snapshot. The view test fires when
  // the line of sight has turned by the threshold since the snapshot was taken (so cards are
  // refreshed as often as without a lead) or lies the threshold away from the snapshot's own
  // direction (a card is never seen further off than the threshold). Flow test bed (20 humans,
  // walking, posture off, 8 degrees, 120 frames): mean tilt of the drawn cards 5.5 -> 3.6 degrees,
  // PSNR +0.54 dB (test bed defaults), +0.28 dB (2 texels, blending, depth-corrected), the same
  // refresh fraction (0.203 -> 0.205) and speed.
  bool lead_cards = true;
  // Leading whole impostors: a whole impostor's snapshot is taken from the eye turned ahead about
  // Ta's vertical, the way the eye has been going round the character (in its frame: the camera's
  // motion and the character's own turns, from the previous planned frame), by view_lead times the
  // view threshold (the view frame's turn; at most the turn of kLeadTimeMax seconds, and two
  // frames' turn short of the threshold). The view test then measures the turn from the
  // snapshot's own view, as without a lead, so no impostor is shown further off than the
  // threshold; the eye passes through the snapshot's view during its life, which lasts
  // (1 + view_lead) times the turn it lasted without. 0: off; in (0, 1]. The scene's camera turned
  // rigidly about Ta's vertical takes it (Ta keeps its pixel, distance and depth: aligned
  // snapshots stay on the screen's grid). Not for part cards (lead_cards). The light stays where
  // it is: the picture is lit as the character stands now. Flow test bed (forty-second session,
  // docs/results.md), poses held, posture off, 8 degrees, 0.5: 20.3 -> 20.7 dB with 25 % fewer
  // refreshes (a larger threshold with about as few, 10-12 degrees: 19.3-18.4 dB); walking, the
  // posture test at 0.4: the speed and image of the threshold that refreshes as often, so off by
  // default.
  float view_lead = 0.0f;
  // Short-lived snapshots drawn as geometry. A refresh draws the character into its window (what
  // drawing it on screen costs), clears the window and draws its quad, so a snapshot that is drawn
  // in one frame only never pays for itself. A character whose cache test fires in the impostor
  // frame right after its last snapshot is drawn as skinned geometry instead, and stays geometry
  // while the test fires from each frame to the next (its cached posture and view move on every
  // frame, as if it had been refreshed); in the first frame where the test does not fire, a
  // snapshot is taken and it is an impostor again. With both thresholds 0 every character is then
  // geometry after its first snapshot. Part cards: per character, when at least half its cards
  // are due one frame after theirs (then all its cards are taken anew). Not with a refresh budget
  // (which holds stale impostors back instead). The characters drawn as geometry go into the
  // impostor frame's target, so this is off by default: they are the geometry's own picture in a
  // single-sampled scene (blended impostors' targets are single-sampled), and there a snapshot
  // costs what drawing the character does (`bodybuilder flow --short-lived auto` turns it on at
  // --msaa 1, and on a GPU, where the flow draws a frame that follows one with such characters
  // into a target of the scene's samples: --impostor-target adaptive). Flow test bed, --msaa 1,
  // both thresholds 0: impostor frame 1.15-1.6 times the geometry's (SimpleSkin 3x) -> 0.96-1.01,
  // the same frames; at 4x with a multisampled impostor target a single-sampled snapshot is the
  // cheaper on llvmpipe (0.63 against 0.98-1.00). On an H200 at 4x the snapshot pass takes 1.5
  // times what the same triangles take in the scene: 0.45 / 0.56 / 0.65x of geometry's speed at
  // 20 / 1,000 / 5,000 humans with snapshots, 1.03 / 0.95 / 0.96x adaptive.
  bool short_lived_as_geometry = false;
};
inline constexpr float kLimbElongation = 2.0f, kLimbFlatness = 1.7f;

// Whether `config` keeps the contracts the atlas and the planner rely on: windows.count in [1, 8],
// window sizes of at least a pixel, largest first; a page_size that holds the largest window (each
// page is a grid of windows of one size); max_pages >= 1; first_page >= 0 and the model's pages
// inside atlas_pages (when not 0); texels_per_pixel finite and > 0; aligned_phase in [0, 1).
// The error names the setting (Error::where, e.g. "ImpostorConfig::page_size") and why.
// Renderer::create returns it; a FramePlanner asserts it (a planner made with a broken config
// anyway draws geometry where it has no window to give).
Status validate_impostor_config(const ImpostorConfig& config);
// The config of the k-th of n models whose renderers share one atlas (ImpostorConfig::first_page):
// `base` with pages [k * max_pages, (k + 1) * max_pages) of n * max_pages.
inline ImpostorConfig shared_atlas_config(ImpostorConfig base, int k, int n) {
  base.first_page = k * base.max_pages;
  base.atlas_pages = n * base.max_pages;
  return base;
}

// Index of `w`'s fitted rectangle (ImpostorConfig::fit_quads_to_coverage) in the renderer's list:
// one slot per smallest-window square of every page (16 bytes each: with 8-pixel windows 256 KB
// for a 1024-pixel page, whose RGBA8 layer takes 4 MB).
inline int coverage_slot(const AtlasWindow& w, int page_size, int smallest_window) {
  const int per_row = page_size / smallest_window;
  return (w.page * per_row + w.y / smallest_window) * per_row + w.x / smallest_window;
}

// Per-instance data the GPU reads (16-byte aligned, plain floats).
struct InstanceGpu {
  glm::vec4 position_yaw;  // world position xyz, yaw
  glm::vec4 anim;          // scale, row of frame f0, row of frame f1, blend f0 -> f1
};
struct BillboardGpu {
  glm::vec4 ta_half;       // world Ta xyz (a part card: its centre), half size (metres)
  glm::vec4 uv_rect;       // u0, v0, u1, v1 of the window in its page
  glm::vec4 layer;         // page (x), coverage slot (y), 1 to fit the quad to the coverage (z); w unused
  glm::vec4 rect;          // used part of the window, in [-1, 1]^2 of the window: x0, y0, x1, y1
  // Part cards (w = 1): the card's half axes in world space (window x and y, metres); w = 0: a
  // quad facing the eye.
  glm::vec4 axis_x{0.0f}, axis_y{0.0f};
  // Depth-corrected part cards (ImpostorConfig::parallax_cards, z > 0): the snapshot's eye
  // offset off the axis (x, y) and distance D from the card plane (z), and the part's radius (w),
  // all in units of the card's half size, so they scale with the carried axes.
  glm::vec4 snap{0.0f};
};
struct SnapshotGpu {
  InstanceGpu instance;
  glm::vec4 ho_half;       // Ho xyz, half size
  glm::vec4 uo_dist;       // Uo xyz, D
  glm::vec4 vo;            // Vo xyz, 1 for a perspective snapshot (0: orthographic)
  glm::vec4 ta;            // Ta xyz, radius
  glm::vec4 window;        // window rect in page NDC: centre x, centre y, half extent; page
  glm::vec4 rect;          // part of the window cleared and drawn, in [-1, 1]^2 of the window:
                           // x0, y0, x1, y1 (the quad's part and a margin)
  glm::vec4 offset{0.0f};  // SnapshotCamera::offset (x, y), metres; z, w unused
  glm::vec4 part{-1.0f};   // x: body part drawn (-1: the whole character); y: coverage slot,
                           // z: 1 to find the covered rectangle (fit_quads_to_coverage); w unused
  glm::vec4 quad{-1.0f, -1.0f, 1.0f, 1.0f};  // the planner's quad in the window (searched for coverage)
};

struct FrameStats {
  int characters = 0;
  int culled = 0;            // outside the view frustum
  int geometry = 0;          // drawn as skinned geometry
  int impostors = 0;         // drawn as impostors
  int snapshots = 0;         // impostors refreshed this frame (a character's part cards count once)
  int part_cards = 0;        // cards drawn for impostors with part cards
  int part_snapshots = 0;    // part cards refreshed (refresh_fraction is then part_snapshots / part_cards)
  float refresh_fraction = 0;  // snapshots / impostors (0 when no impostor)
  int atlas_fallbacks = 0;   // wanted an impostor, atlas full: drawn as geometry
  // Characters whose windows were taken back for others this frame: characters not drawn as
  // impostors in it (culled, or geometry), the longest undrawn first, when the atlas was full.
  int atlas_reclaimed = 0;
  // window_refreshes: a new window size class, or a snapshot cut at a scale seen 1.5 times larger.
  int posture_refreshes = 0, view_refreshes = 0, window_refreshes = 0, new_snapshots = 0;
  int deferred_refreshes = 0;  // stale impostors kept one more frame by CacheConfig::refresh_budget
  int ahead_refreshes = 0;     // impostors refreshed before their thresholds (CacheConfig::ahead_fraction)
  // Characters drawn as geometry instead of a snapshot that would be drawn in one frame only
  // (ImpostorConfig::short_lived_as_geometry; counted in `geometry`, not in `snapshots`).
  int short_lived_geometry = 0;
  int lead_snapshots = 0;  // whole impostors' snapshots taken ahead (ImpostorConfig::view_lead)
  std::array<int, 8> geometry_per_lod{};  // characters per LOD level
  std::array<int, 8> impostors_per_window{};
  std::size_t geometry_triangles = 0;  // drawn this frame by the geometry path
  std::size_t snapshot_triangles = 0;  // drawn into the atlas this frame
  double quad_texels = 0;              // window texels the impostor quads cover (their fill, in texels)
  int atlas_pages_used = 0, atlas_pages = 0, atlas_windows_used = 0;
  float atlas_pixel_use = 0;           // fraction of the used pages' pixels in windows
  // Threads that planned the crowd (1: the calling thread alone; FramePlanner::kRefreshWork).
  int planner_threads = 1;
};

// What to draw this frame. Geometry instances and snapshots are grouped by LOD level (a
// snapshot's page is in its `window.w`).
struct FramePlan {
  std::vector<std::vector<InstanceGpu>> geometry;  // [lod] -> instances
  std::vector<BillboardGpu> billboards;
  std::vector<std::vector<SnapshotGpu>> snapshots;  // [lod] -> snapshots drawn with that level
  SceneCamera camera;
  FrameStats stats;
  // The impostor cache the plan's quads draw from: a FramePlanner makes a new one when it is made
  // and at each invalidate(). The quads show windows whose snapshots were taken in this plan or in
  // the `cache_plans_before` earlier plans of the same cache that took snapshots, so those must
  // have been drawn by the renderer that draws this plan (Renderer::holds_snapshots_for; 0: the
  // plan needs no earlier snapshot, any renderer of the model and config can draw it).
  std::uint64_t cache_id = 0;
  std::uint32_t cache_plans_before = 0;
  // Set by Renderer::draw when it does not hold those snapshots (a renderer made anew, or another
  // one): the quads showed empty windows, and the planner that made this plan takes every snapshot
  // anew at its next frame (one frame without those impostors; invalidate() before the new
  // renderer's first plan avoids it). Only the planner's own plan (plan_of_last_frame) carries it back.
  mutable bool drawn_from_another_atlas = false;
};

class WorkerPool;

class FramePlanner {
 public:
  // Crowds from this much work on are planned on ImpostorConfig::planner_threads threads, where a
  // crowd's work is its size (with part cards, its cards: each is tested every frame, 2.4 us a
  // 16-part CesiumMan) plus kRefreshWork for each impostor the previous frame refreshed (a
  // refresh costs about that many characters' planning: its snapshot camera, window and tight
  // quad; CesiumMan 0.77 us against 0.07-0.12 us). So the test bed's worst case, every
  // character refreshed every frame, is planned on threads at 250 characters a model too.
  static constexpr std::size_t kParallelCharacters = 512;
  static constexpr std::size_t kRefreshWork = 8;
  // ... on one thread per this much work at most (up to planner_threads). On the H200's 16-thread
  // host (fifty-second session, flow test bed, our four bodies, three alternated runs each) 32
  // against 512 planned 1,000 humans in 0.18-0.19 ms against 0.28-0.31 (2.29-2.55x geometry's
  // speed at 8 degrees against 1.91-2.09x; 128: 0.21-0.26 ms), 2,000 in 0.24-0.26 ms against
  // 0.34-0.41; 10,000 take every thread either way. A 2-core machine is at two threads from 64.
  static constexpr std::size_t kCharactersPerThread = 32;
  // ... in chunks of at least this many characters (four chunks a thread of the pool).
  static constexpr std::size_t kCharactersPerChunk = 32;
  // ... and stale impostors reached by the refresh budget on one thread per this many (a refresh
  // costs tens of times a character's planning).
  static constexpr std::size_t kForcedPerThread = 32;
  // Leading part cards: the look-ahead's step (seconds) and its most steps.
  static constexpr float kLeadStep = 1.0f / 30.0f;
  static constexpr int kLeadSteps = 45;
  // Leading whole impostors (ImpostorConfig::view_lead): the turn of at most this many seconds.
  static constexpr float kLeadTimeMax = kLeadStep * kLeadSteps;
  FramePlanner(const Model& model, const ImpostorConfig& config = {});

  // Plans one frame of `crowd` (of this planner's model) seen by `camera` at scene time `time`
  // (seconds). kGeometry and kImpostor/kAuto frames may be interleaved: geometry frames leave the
  // impostor cache untouched. The returned plan stays valid until the next call.
  const FramePlan& plan(const Crowd& crowd, const SceneCamera& camera, float time, RenderMode mode);

  // One frame of several planners (one per model, each with its crowd: crowds[k] is of
  // planners[k]'s model), every plan the same as plan() would make, planned together: the
  // crowds' chunks in one call on planners[0]'s threads instead of one call per model (the
  // wake-ups and the waits for the last thread are paid once). A crowd too small for threads on
  // its own is chunked too where the crowds' joint work is enough; its plan then lists the
  // characters whose atlas windows changed after the others, as a chunked crowd's does (the same
  // entries as plan()'s, whatever the threads). The plans are then each planner's
  // plan_of_last_frame(). Planners must be distinct.
  static void plan_many(std::span<FramePlanner* const> planners, std::span<const Crowd* const> crowds,
                        const SceneCamera& camera, float time, RenderMode mode);
  // What the last plan() or plan_many() returned or made; valid until the next.
  const FramePlan& plan_of_last_frame() const { return plan_; }

  // Forces a new snapshot of every impostor at the next impostor frame, and starts a new cache
  // (FramePlan::cache_id). The snapshots a planner keeps (its cache) are pictures in the atlas of
  // the renderer that drew its plans: a plan draws windows whose snapshots earlier plans took. A
  // renderer made anew (after a context loss, a change of settings), or another renderer than the
  // one that drew the earlier plans, holds none of them: call invalidate() before its first plan
  // (Renderer::holds_snapshots_for tells). Without it the renderer draws that plan's impostors from
  // empty windows (invisible for a frame) and marks the plan (FramePlan::drawn_from_another_atlas),
  // and this planner invalidates itself at its next frame. One renderer's atlas
  // holds one planner's snapshots: two views of one crowd need a planner (and renderer) each.
  void invalidate();
  // The config, to change between frames. The cache tests, the refresh policies, the kAuto switch,
  // part cards on or off, texels per pixel (a character whose window size class changes is taken
  // anew) and planner_threads take effect at the next frame. The fields that only change how a
  // snapshot is taken (aligned_snapshots, aligned_phase, perspective_snapshots, snapshot_distance,
  // texel_per_pixel, tight_quads, snapshot_lod_from_screen, fit_quads_*, view_lead, lead_cards)
  // apply to the snapshots taken after the change: impostors keep their old pictures until their
  // cache tests fire, unless invalidate() is called. The atlas's fields (windows, page_size,
  // max_pages, first_page, atlas_pages) and those the Renderer was made with (snapshot_samples,
  // impostor_taps, relight, parallax_cards, ...) must not change: make a new planner and renderer.
  ImpostorConfig& config() { return config_; }
  const ImpostorConfig& config() const { return config_; }
  const Model& model() const { return *model_; }
  const AtlasAllocator& atlas() const { return atlas_; }
  // LOD level the geometry path uses for an on-screen diameter of `pixels` in a viewport
  // `viewport_height` pixels high (MSFT_screencoverage: diameter / height >= coverage).
  int lod_for(float pixels, int viewport_height) const;
  // Window `w`'s index in the renderer's list of coverage rectangles (coverage_slot).
  int coverage_slot_of(const AtlasWindow& w) const;

 private:
  struct CacheState {
    std::array<float, 4> posture{};
    glm::mat3 view{1.0f};
    float half_size = 0.0f;  // of the billboard, metres, from the last snapshot
    float scale = 1.0f;      // the character's Character::scale then (its quad scales with it since)
    // Aligned snapshots: the window's centre minus Ta along the camera's right and up (metres);
    // the quad is then drawn parallel to the screen (`aligned`), else facing the eye.
    glm::vec2 offset{0.0f};
    bool aligned = false;
    bool fitted = false;  // its quad is fitted to the coverage (found with the snapshot)
    bool led = false;     // taken ahead of the eye (ImpostorConfig::view_lead)
    // ImpostorConfig::short_lived_as_geometry: drawn as geometry, its posture and view moved on
    // without a snapshot, so the window holds an older picture (refreshed before it is drawn).
    bool picture_behind = false;
    std::uint32_t taken = 0;  // impostor frame (FrameSetup::frame) the last snapshot was taken in
    // The last impostor frame the character was drawn in as an impostor (its window, or its part
    // cards' windows, in use): a window held by a character not drawn in the frame being planned
    // may be taken back when the atlas is full (reclaim), the longest undrawn first.
    std::uint32_t drawn = 0;
    // Aligned snapshots: the screen's right and up axes when the snapshot was cut, in the frame of
    // the line of sight to Ta (section 4.2's Ho, Uo, Vo, taken with the world's up). Its quad is drawn
    // along the current screen axes, which gives the picture back while these hold (a still camera,
    // one orbiting the crowd); a camera turned or rolled in place (mouse look) turns them and no line
    // of sight in the character's frame: refreshed when they have turned past the view threshold.
    glm::vec3 screen_right{1.0f, 0.0f, 0.0f}, screen_up{0.0f, 1.0f, 0.0f};
    glm::vec4 rect{-1, -1, 1, 1};  // part of the window the last snapshot used
    AtlasWindow window;
    bool valid = false;
    std::uint32_t owner = 0;  // Character::id of the character this slot is for
    // Leading part cards (ImpostorConfig::lead_cards) and whole impostors (view_lead): the eye in
    // the character's frame at the last planned frame, and that frame's time; whole impostors also
    // keep the eye's velocity there (units per second) from the frame before.
    glm::vec3 eye_char{0.0f}, eye_vel{0.0f};
    float eye_time = 0.0f;
    float eye_step = 0.0f;  // seconds between the two frames eye_vel is measured over
    bool eye_valid = false;
  };
  // Part cards: per character and part, the card in the bone's palette space at snapshot time.
  struct PartCache {
    glm::vec3 centre{0.0f}, axis_x{0.0f}, axis_y{0.0f};  // centre, half axes (palette space)
    glm::vec3 normal{0.0f, 0.0f, 1.0f};  // line of sight to the part when it was taken (palette space)
    glm::vec3 card_normal{0.0f, 0.0f, 1.0f};  // Vo of the snapshot (palette space; = normal without a lead)
    glm::vec4 snap{0.0f};                // BillboardGpu::snap (parallax_cards)
    std::array<float, 4> posture{};      // the character's posture distances when it was taken
    float half_size = 0.0f;
    glm::vec4 rect{-1, -1, 1, 1};
    AtlasWindow window;
    bool fitted = false;
    std::uint32_t taken = 0;  // as CacheState::taken
  };
  // A stale impostor's refresh, held back until the frame's budget is shared out.
  // (end_frame works out the refresh of those the budget reaches.)
  struct PendingRefresh {
    float staleness = 0.0f;  // > 1: how far past its thresholds
    std::uint32_t order = 0, billboard = 0;  // the character's index in the crowd; in plan_.billboards
  };
  // What a part card's refresh needs of its character's frame: worked out at once, or, for a
  // stale card waiting on the refresh budget, in end_frame if the budget reaches it.
  struct PartJob {
    std::uint32_t character = 0;
    int part = 0;
    glm::mat4 bone{1.0f};  // placement x the part's bone matrix now
    glm::vec3 centre{0.0f};
    float depth = 0.0f;  // of the centre along the view direction
    InstanceGpu inst;
    std::array<float, 4> posture{};
    int slod = 0, clip = 0;
    bool lead = false;  // ImpostorConfig::lead_cards: the eye in the character's frame and its velocity
    glm::vec3 eye_char{0.0f}, eye_vel{0.0f};
    float cos_view = 1.0f;  // of the character's (weighted) view threshold
  };
  // A stale part card's refresh, held back until the frame's budget is shared out.
  struct PendingPart {
    float staleness = 0.0f;
    std::uint32_t order = 0, billboard = 0;  // the card's index in part_cache_; in plan_.billboards
    std::uint32_t job = 0;                   // in part_jobs_
  };
  // What plan_character needs of the frame (the same for every character), set by begin_frame.
  struct FrameSetup {
    SceneCamera camera;
    std::array<glm::vec4, 6> planes{};  // frustum, world
    glm::vec3 cam_right{0.0f}, cam_up{0.0f}, fwd{0.0f};
    float ppm1 = 0, cos_view = 0, switch_px = 0, page = 0, time = 0;
    float cos_ahead = 1;  // of CacheConfig::ahead_fraction of the (unweighted) view threshold
    bool impostor_mode = false, budget = false;
    bool ahead = false;  // CacheConfig::ahead_fraction on (whole impostors)
    RenderMode mode = RenderMode::kAuto;
    std::uint32_t frame = 0;  // impostor frames planned so far, this one included
    std::array<int, 8> window_lod{};  // LOD of each window class
  };
  // Where snapshots go: the plan's lists by LOD, or a chunk's one list with each snapshot's LOD
  // beside it (room for all its characters' cards; end_frame joins them by LOD, in order).
  struct SnapshotSink {
    std::vector<std::vector<SnapshotGpu>>* by_lod = nullptr;
    std::vector<SnapshotGpu>* list = nullptr;
    std::vector<std::uint8_t>* lods = nullptr;
    void add(int lod, const SnapshotGpu& s) const {
      if (by_lod) {
        (*by_lod)[static_cast<std::size_t>(lod)].push_back(s);
      } else {
        list->push_back(s);
        lods->push_back(static_cast<std::uint8_t>(lod));
      }
    }
  };
  // Where plan_character writes: the plan's lists, or a chunk's. `deferred` set: characters whose
  // atlas window must be allocated or changed are only listed there (a parallel pass).
  struct Out {
    std::vector<std::vector<InstanceGpu>>* geometry;
    SnapshotSink snapshots;
    std::vector<BillboardGpu>* billboards;
    std::vector<PendingRefresh>* pending;
    FrameStats* st;
    int* budget_used;
    std::vector<std::uint32_t>* deferred;
    bool forced = false;  // a stale impostor the budget reached: refreshed, not left pending
    // Impostors past CacheConfig::ahead_fraction of their thresholds, not stale (null: not listed).
    std::vector<PendingRefresh>* ahead = nullptr;
    bool ahead_now = false;  // one of those, chosen: refreshed (with `forced`)
    // Part cards: stale cards held back for the budget, and their jobs (PendingPart::job indexes
    // `part_jobs`).
    std::vector<PendingPart>* pending_parts = nullptr;
    std::vector<PartJob>* part_jobs = nullptr;
    // Characters whose window could not be allocated, the atlas being full: listed here (not null:
    // end_frame's serial pass) to be planned again once every other character of the frame is
    // (`reclaim` set: then windows of characters not drawn this frame may be taken back for them).
    std::vector<std::uint32_t>* starved = nullptr;
    bool reclaim = false;
  };
  // A chunk's lists and counters, written by one thread: on cache lines of their own (a counter
  // beside the next chunk's list heads would be written by two threads at once).
  struct alignas(128) Chunk {
    std::vector<std::vector<InstanceGpu>> geometry;
    std::vector<SnapshotGpu> snapshots;
    std::vector<std::uint8_t> snapshot_lods;
    SnapshotSink sink() { return SnapshotSink{nullptr, &snapshots, &snapshot_lods}; }
    // Its snapshots into `by_lod`, each after those of its level already there.
    void join_snapshots(std::vector<std::vector<SnapshotGpu>>& by_lod) const {
      for (std::size_t j = 0; j < snapshots.size(); ++j) by_lod[snapshot_lods[j]].push_back(snapshots[j]);
    }
    std::vector<BillboardGpu> billboards;
    std::vector<PendingRefresh> pending;
    std::vector<PendingRefresh> ahead;
    std::vector<std::uint32_t> deferred;
    std::vector<PendingPart> pending_parts;
    std::vector<PartJob> part_jobs;
    FrameStats st;
    int budget_used = 0;
    // Empties the lists for `characters` characters of `cards` cards in all (part cards; else as
    // many as characters), each list holding room for all of them (which LOD or list a character
    // takes changes from frame to frame: no allocation once warm; about 0.4 kB a card).
    void clear(std::size_t lods, std::size_t characters, std::size_t cards);
  };
  // Plans character i: culling, geometry LOD or impostor (cache tests, snapshot, card).
  void plan_character(std::size_t i, const Character& ch, const FrameSetup& fs, const Out& out);
  unsigned planner_threads();  // starts the pool when more than one thread is wanted
  unsigned max_useful_threads(std::size_t work);  // at most planner_threads()
  // A frame in three steps: begin_frame (serial; returns the number of chunks to plan, 0: the
  // crowd is planned serially by end_frame), plan_chunk for each (any thread, any order),
  // end_frame (joins the chunks, serves the budget, returns the plan). join_chunks, end_frame's
  // first part, touches this planner's own lists only: plan_many runs several planners' on the
  // threads before their end_frame (which then does not join again).
  std::size_t begin_frame(const Crowd& crowd, const SceneCamera& camera, float time, RenderMode mode);
  // Splits begin_frame's crowd into chunks (if not already, and not empty); returns their number.
  std::size_t chunk_frame();
  // Moves the cache slots (and part cards) with their characters' ids where the crowd has changed
  // other than at its end, releasing the windows of characters no longer in it (begin_frame).
  void follow_ids(const Crowd& crowd);
  void plan_chunk(std::size_t c);
  void join_chunks();
  const FramePlan& end_frame();
  void refresh_listed(const std::vector<PendingRefresh>& list, std::size_t take, bool ahead);
  // A window of class `size_class` for a starved character (end_frame): allocated, or, the atlas
  // being full, taken back from the characters not drawn as impostors this frame (reclaim).
  std::optional<AtlasWindow> allocate_or_reclaim(int size_class, bool reclaim);
  // Takes back the windows of one character not drawn this frame so that a window of `size_class`
  // can be allocated: the longest undrawn holding one of that class, else every character holding
  // a window of one page that only such characters use (the page is then free for any class).
  // False when there is none. Linear in the crowd once a frame (on its first call), amortized O(1)
  // a window after.
  bool reclaim(int size_class);
  void release_character_windows(std::size_t i);  // reclaim's: character i's windows back to the atlas
  // The frame being planned.
  struct Frame {
    const Crowd* crowd = nullptr;
    FrameSetup setup;
    FrameStats st;
    int budget_used = 0;
    std::size_t chunks = 0;
    bool joined = false;   // join_chunks has run
    std::size_t work = 0;  // the crowd's size and the last frame's refreshes (kRefreshWork each)
    unsigned threads = 1;  // that planned the chunks
  };
  Frame frame_;
  const Model* model_;
  ImpostorConfig config_;
  std::shared_ptr<WorkerPool> pool_;
  std::vector<Chunk> chunks_;
  std::vector<PendingRefresh> pending_;
  std::vector<PendingRefresh> ahead_;  // CacheConfig::ahead_fraction's candidates this frame
  std::vector<PendingPart> pending_parts_;
  std::vector<PartJob> part_jobs_;
  std::vector<std::uint8_t> refreshed_;  // part cards: characters with a card refreshed this frame
  int budget_left_ = 0;  // CacheConfig::refresh_budget left in the frame being planned
  int last_snapshots_ = 0;  // impostors refreshed by the last frame planned (Frame::work)
  AtlasAllocator atlas_;
  std::uint64_t cache_id_ = 0;         // FramePlan::cache_id (new at each invalidate())
  std::uint32_t cache_plans_ = 0;      // plans of that cache that took snapshots
  std::vector<std::uint32_t> starved_;  // Out::starved of the frame being planned
  // reclaim's candidates, found at its first call in a frame: the characters holding windows that
  // were not drawn in it, the longest undrawn first (by the bit length of the frames since, so no
  // sort), with how many windows they hold in each page and, per window class, how far its
  // search has gone.
  struct Reclaim {
    std::uint32_t frame = 0;  // FrameSetup::frame they were found in (0: none yet)
    std::vector<std::uint32_t> found, order;
    std::vector<int> page_windows;
    std::array<std::size_t, 8> next{};
  };
  Reclaim reclaim_;
  std::vector<CacheState> cache_;
  std::vector<PartCache> part_cache_;  // [character * parts + part] when part cards are on
  // follow_ids' scratch: the slots in their new order, each character's old slot, which old slots
  // are taken, the others by owner (an open-addressed table).
  struct Follow {
    std::vector<CacheState> cache;
    std::vector<PartCache> parts;
    std::vector<std::uint32_t> from;
    std::vector<std::uint8_t> taken;
    std::vector<std::pair<std::uint32_t, std::uint32_t>> table;
  };
  Follow follow_;
  int parts_ = 1;                      // parts per character (1: ordinary impostors)
  // A part card's new card (and its snapshot, and the snapshot's triangles), in the frame being
  // planned (frame_.setup: its camera, time and frame number).
  PartCache part_card(const PartJob& job, const Character& ch, SnapshotGpu& s, std::size_t& tris) const;
  glm::vec3 lead_direction(const PartJob& job, const Character& ch, float time) const;
  // Whether a snapshot taken in impostor frame `frame` gets its quad fitted to the coverage, the
  // snapshot it replaces having been taken in frame `last` (0: none).
  bool fit_quad(std::uint32_t last, std::uint32_t frame) const;
  BillboardGpu part_billboard(const PartCache& c, const glm::mat4& bone, const glm::mat3& turn) const;
  // Plans character i's part cards (windows, cache tests, snapshots, cards) into `out`: kGeometry
  // when the atlas is full or its snapshots would live one frame (the character is then drawn as
  // geometry), kDeferred when a window must be allocated or changed in a parallel pass (`out.deferred`
  // set: planned again in crowd order by end_frame).
  enum class PartsPlanned { kCards, kGeometry, kDeferred };
  PartsPlanned plan_parts(std::size_t i, const Character& ch, const BakedClip& bc, int f0, int f1, float blend,
                          const InstanceGpu& inst, const glm::vec3& ta, float radius, float pixels,
                          const SceneCamera& camera, float time, const Out& out);
  FramePlan plan_;
};

}  // namespace bb::runtime
