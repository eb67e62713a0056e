// The impostor logic of the paper as plain C++ (no GL): the scene camera, the orthographic
// snapshot camera (section 4.2), the two cache tests (section 5), the texture-window size
// (section 4.3) and the allocator of windows in shared atlas pages.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include <glm/glm.hpp>

namespace bb::runtime {

// The scene ("subjective") camera: perspective, looking from `eye` at `target` (which must differ).
struct SceneCamera {
  glm::vec3 eye{0.0f, 1.6f, 10.0f};
  glm::vec3 target{0.0f, 1.0f, 0.0f};
  // Us, need not be unit. Parallel to the view direction (a camera looking straight down with up
  // +Y) or zero: view() takes +Z instead (+X when the view direction is along Z), as the impostor
  // quads and make_snapshot_camera do.
  glm::vec3 up{0.0f, 1.0f, 0.0f};
  float fov_y = 0.7854f;            // radians, vertical field of view
  int width = 1280, height = 1024;  // viewport, pixels
  float near_plane = 0.1f, far_plane = 1000.0f;  // metres

  glm::mat4 view() const;
  glm::mat4 projection() const;
  // The up vector view() takes: `up`, or another one where `up` is parallel to the view direction.
  glm::vec3 view_up() const;
  // Pixels per metre at distance `depth` (metres along the viewing direction).
  float pixels_per_metre(float depth) const;
};

// Section 4.2: Vo = unit(Ta - eye), Ho = Vo x Us, Uo = Ho x Vo, To = Ta - D Vo. The frustum is a
// square of half size `half_size` around Ta in the plane through Ta normal to Vo, depth Ta +- the
// model's radius.
//  - orthographic (the paper): half_size = radius, D arbitrary;
//  - perspective (our default): D = |Ta - eye|, so To is the eye itself, and half_size =
//    radius * D / sqrt(D^2 - radius^2) holds the sphere's projection. Drawn on a plane at Ta
//    facing the eye, such a snapshot reproduces the geometry exactly at the moment it is taken
//    (the orthographic one is off by the perspective of the body's depth, several pixels at
//    256-pixel windows). With the eye inside 1.05 radius it falls back to orthographic.
struct SnapshotCamera {
  glm::vec3 ta{0.0f};        // world
  glm::vec3 vo{0.0f, 0.0f, -1.0f}, ho{1.0f, 0.0f, 0.0f}, uo{0.0f, 1.0f, 0.0f};  // unit, world
  glm::vec3 to{0.0f};        // camera position, world
  float half_size = 1.0f;    // metres, in the plane through Ta
  float radius = 1.0f;       // metres: the character's bounding sphere around Ta
  float distance = 2.0f;     // D, metres (orthographic: does not change the picture)
  bool perspective = false;
  // Perspective only: the eye lies off the axis through ta, at ta - distance Vo - offset.x Ho -
  // offset.y Uo (metres): an off-axis window, as cut out of the scene camera's image
  // (make_aligned_snapshot_camera). Zero for make_snapshot_camera's cameras.
  glm::vec2 offset{0.0f};

  glm::mat4 view() const;        // world -> camera (right-handed, looks along vo)
  glm::mat4 projection() const;  // [-h, h]^2 at Ta; near D - radius, far D + radius
};

// Returns the snapshot camera for a character whose poses fit in a sphere of `radius` around Ta.
// Orthographic: `distance` <= 0 uses 2 * radius. When Vo is parallel to Us the frame falls back
// to a horizontal Ho so the result is always a right-handed frame.
SnapshotCamera make_snapshot_camera(const glm::vec3& ta, const glm::vec3& eye, const glm::vec3& up,
                                    float radius, float distance = 0.0f, bool perspective = false);

// The camera's right, up and forward axes (orthonormal, world; forward looks from eye to target).
void camera_axes(const SceneCamera& camera, glm::vec3& right, glm::vec3& up, glm::vec3& forward);

// Diameter in pixels of the box around the projection of a sphere (`centre`, `radius`, world) in
// `camera`'s image, centred on the centre's projection: what an aligned snapshot's window must
// hold. Exact for the sphere (the tangent planes through the eye), so wider than 2 r ppm / depth
// off the axis. Infinite when the eye is within 1.05 radius of the centre or behind it.
float aligned_pixels(const SceneCamera& camera, const glm::vec3& centre, float radius);
// The same from the camera's eye, its axes (camera_axes) and pixels_per_metre(1): for a caller that
// asks it of many centres in one frame (the planner, every character every frame).
float aligned_pixels(const glm::vec3& eye, const glm::vec3& right, const glm::vec3& up, const glm::vec3& forward,
                     float pixels_per_metre_at_1, const glm::vec3& centre, float radius);

// A snapshot camera whose texels lie on the scene camera's pixels: its image plane is the
// screen's (Ho, Uo, Vo = the camera's right, up, forward), its window of `window_texels` texels
// is centred on the screen pixel corner nearest to the centre's projection, and
// `texels_per_pixel` texels cover one pixel (1: texel for pixel; 2: 2x2 texels per pixel). Drawn
// on the plane through ta parallel to the screen, such a snapshot is the geometry's own picture
// at the moment it is taken, with no resampling. nullopt when the window cannot hold the sphere
// at that scale (aligned_pixels * texels_per_pixel > window_texels) or the eye is inside it.
// `phase` (pixels, 0 <= phase < 1) moves the window's centre that far right of and above the
// pixel corner, both axes, so that the texel grid sits that far off the pixel grid (at one texel
// per pixel, texel centres phase right of and above pixel centres): ImpostorConfig::aligned_phase.
std::optional<SnapshotCamera> make_aligned_snapshot_camera(const SceneCamera& camera, const glm::vec3& centre,
                                                           float radius, int window_texels, float texels_per_pixel,
                                                           float phase = 0.0f);

// Section 5.2: the "view matrix" of a character = the snapshot camera's frame expressed in the
// character's frame (camera x character): columns Ho, Uo, -Vo rotated by the inverse of the
// character's rotation (a yaw about +Y, radians).
glm::mat3 view_rotation(const SnapshotCamera& cam, float yaw);

// Angle in radians of the rotation between two rotation matrices (axis-angle of A^T B).
float rotation_angle(const glm::mat3& a, const glm::mat3& b);
// Same test without acos: (trace(A^T B) - 1) / 2, the cosine of that angle.
inline float rotation_cosine(const glm::mat3& a, const glm::mat3& b) {
  float t = glm::dot(a[0], b[0]) + glm::dot(a[1], b[1]) + glm::dot(a[2], b[2]);
  return 0.5f * (t - 1.0f);
}

// Section 5: when a snapshot is stale.
struct CacheConfig {
  bool posture_test = true;
  // Relative change of any of the four squared joint-pair distances (0.4 = 40 %; 0: any change).
  float posture_threshold = 0.4f;
  bool view_test = true;
  // Degrees. 0 refreshes on any turn, also one too small for its cosine to show in floats (below
  // 3e-4 radians); part cards: any turn above the 1e-6 radians their carried normals round to.
  float view_threshold_deg = 8.0f;
  // Optional distance weighting of both thresholds (the paper's): threshold * max(1, distance /
  // reference_distance).
  bool distance_weighting = false;
  float reference_distance = 10.0f;  // metres
  // Optional screen-size weighting of both thresholds: threshold * max(1, reference_pixels /
  // the character's size on screen in pixels, its bounding sphere's diameter) (0: off). The paper's distance weighting tied to
  // the picture instead of to metres: a character shorter than reference_pixels is refreshed as
  // if its changes were scaled up to that height, so a 5-pixel walker is not re-drawn every half
  // step for a sub-pixel change of pose. Thresholds of 0 stay 0. Where both are on, the larger
  // weight counts. Flow test bed (posture 0.4, view 8 degrees, llvmpipe), 32 pixels: 10,000
  // humans 8.7x -> 34.9x geometry's speed (refresh fraction 0.11 -> 0); 1,000 humans 7.6x -> 12.4x
  // at 16.93 -> 16.06 dB; 20 humans (75-100 pixels tall) unchanged.
  float reference_pixels = 0.0f;
  // The paper's section 7, item 1: a crowd-level refresh policy for a quasi-constant frame rate.
  // At most this many impostors are refreshed per frame (0: no limit). Impostors without a usable
  // snapshot (new, or their window size class changed) are always refreshed and count first;
  // the budget left goes to the stale ones, most stale first (staleness: the larger of the view
  // angle and the largest posture change, each over its threshold, so > 1), and the others keep
  // their snapshot one more frame (FrameStats::deferred_refreshes). A deferred impostor only grows
  // staler, so none waits for ever unless the budget is below the steady demand. With part cards
  // the unit is a card (each card keeps the posture it was taken at, and its staleness is its tilt
  // over the view threshold or its posture change over the posture threshold).
  int refresh_budget = 0;
  // Refreshes ahead, a crowd-level policy too: a frame that takes snapshots anyway (some impostor
  // is stale or new) also refreshes up to `ahead_count` impostors whose staleness (as the budget
  // measures it) is past `ahead_fraction` of their thresholds, the stalest first, so that the
  // refreshes gather in fewer frames. A frame without a snapshot skips the snapshot pass and its
  // fixed costs (the framebuffer switch, the state changes, the coverage pass and the wait for the
  // snapshots before the quads). No impostor is drawn past its thresholds, and those refreshed
  // ahead are younger than they would have been. Whole impostors only (part cards take snapshots
  // in nearly every frame). 0: off; else in (0, 1). Within a refresh budget they take what it
  // leaves.
  float ahead_fraction = 0.0f;
  int ahead_count = 4;
};

// Multiplier of the thresholds for a character `distance` metres from the eye, `pixels` tall on
// screen (CacheConfig::distance_weighting, reference_pixels); 1 when neither is on.
inline float distance_weight(const CacheConfig& c, float distance, float pixels = 0.0f) {
  float w = 1.0f;
  if (c.distance_weighting && c.reference_distance > 0.0f) w = std::max(w, distance / c.reference_distance);
  if (c.reference_pixels > 0.0f && pixels > 0.0f) w = std::max(w, c.reference_pixels / pixels);
  return w;
}

// Section 5.1: true when any pair's squared distance changed by more than `threshold` relative
// to its value at the last snapshot (a stored value of 0 compares absolutely, in m^2).
inline bool posture_changed(const std::array<float, 4>& stored, const std::array<float, 4>& now,
                            float threshold) {
  bool changed = false;
  for (int k = 0; k < 4; ++k) {
    float d = now[k] - stored[k];
    d = d < 0.0f ? -d : d;
    float ref = stored[k] > 0.0f ? stored[k] : 1.0f;
    changed |= d > threshold * ref;
  }
  return changed;
}

// Section 4.3: window sizes, largest first (pixels, powers of two are usual but not required).
// The paper's 256, 128, 64 and 32 serve 20 humans on a 1280x1024 screen; 16 and 8 serve the
// characters a few pixels high of large crowds, whose snapshots in 32-pixel windows scattered
// their few covered texels over the atlas (RiggedSimple, 10,000 humans of 6-16 pixels, nothing
// refreshed: the impostor quads read 10 atlas pages instead of 2, and the frame's rasterization
// took 11.2-13.9 ms against 8.8-9.8 ms; a 4-pixel class added nothing there).
struct WindowSizes {
  std::array<int, 8> size{256, 128, 64, 32, 16, 8};
  int count = 6;
};

// Index of the smallest window that still holds `pixels` (the character's on-screen diameter);
// 0 (the largest) when none does.
int choose_window(const WindowSizes& sizes, float pixels);

// A window in an atlas page. Pages are square, `page_size` pixels; each page holds windows of one
// size class on a regular grid, so allocation and release are O(1) and pages are shared by many
// characters.
struct AtlasWindow {
  std::int32_t page = -1;  // -1: none
  std::int32_t x = 0, y = 0;  // pixels, lower-left corner in the page (GL convention)
  std::int32_t size = 0;      // pixels
  std::int32_t size_class = 0;
  std::int32_t slot = 0;      // index inside the page
  bool valid() const { return page >= 0; }
};

class AtlasAllocator {
 public:
  // `page_size` >= the largest window; `max_pages` >= 1. The windows' pages are numbered from
  // `first_page` (an atlas shared with other allocators: ImpostorConfig::first_page).
  AtlasAllocator(int page_size, int max_pages, const WindowSizes& sizes, int first_page = 0);

  // A free window of class `size_class`; nullopt when every page is in use and full, and for a
  // class whose windows do not fit in a page (a broken contract, asserted; no window then rather
  // than a page of none).
  std::optional<AtlasWindow> allocate(int size_class);
  void release(const AtlasWindow& w);  // `w` must come from allocate and not be released twice
  void clear();

  int page_size() const { return page_size_; }
  int max_pages() const { return static_cast<int>(pages_.size()); }
  int first_page() const { return first_page_; }
  int pages_used() const;
  int windows_used() const { return windows_used_; }
  // Fraction of the used pages' pixels covered by windows in use.
  float pixel_use() const;
  // Class of page `p` (numbered as the windows are, from first_page()), or -1 when it is unused.
  int page_class(int p) const { return pages_[static_cast<std::size_t>(p - first_page_)].size_class; }
  // Windows in use in page `p` (numbered as page_class's).
  int page_windows(int p) const { return pages_[static_cast<std::size_t>(p - first_page_)].used; }

 private:
  struct Page {
    int size_class = -1;  // -1: empty
    int per_row = 0;
    std::vector<std::int32_t> free_slots;
    int used = 0;
  };
  int page_size_;
  int first_page_;
  WindowSizes sizes_;
  std::vector<Page> pages_;
  std::array<std::vector<int>, 8> open_pages_;  // per class: pages with a free slot
  int windows_used_ = 0;
};

}  // namespace bb::runtime
