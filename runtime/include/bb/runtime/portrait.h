// One character rendered alone, headless-friendly: what `bodybuilder render` and the image tests
// use. Needs a current OpenGL 4.5 core context (see headless.h).
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "bb/result.h"
#include "bb/runtime/crowd.h"
#include "bb/runtime/model.h"

namespace bb::runtime {

struct PortraitOptions {
  RenderMode mode = RenderMode::kGeometry;  // kGeometry or kImpostor
  int clip = 0;
  float time = 0.0f;            // seconds into the clip (looped)
  float azimuth_deg = 0.0f;     // 0: in front (+Z side); 90: from the character's left (+X)
  float elevation_deg = 10.0f;  // above the horizon through Ta
  float distance = 0.0f;        // metres from Ta; <= 0: the snapshot sphere fills 90 % of the height
  float fov_y_deg = 30.0f;
  int width = 512, height = 512;
  bool orthographic = false;    // the paper's orthographic snapshot instead of the perspective one
};

struct Image {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgba;  // rows top to bottom, transparent background
  FrameStats stats;
  int window_pixels = 0;           // impostor mode: the snapshot window's size (1:1 with the screen)
};

// The camera orbiting the model's Ta that PortraitOptions describes.
SceneCamera portrait_camera(const Model& model, const PortraitOptions& options);

// Renders the model once, as geometry or as an impostor whose snapshot is taken at the same time
// and view with a window of the character's on-screen size (one texel per pixel at Ta's depth).
// Makes its renderer and target for this one picture: for many, use a PortraitRenderer.
Result<Image> render_portrait(const Model& model, const PortraitOptions& options);

// Renders one model again and again (an animation, a spinning view, portraits for a UI): the
// renderer (its shader programs, atlas) and the target are made on the first call and kept while
// the picture's size, the snapshot window's size and the projection stay the same; otherwise they
// are made again. Every picture is what render_portrait gives for the same options (an impostor
// is always a fresh snapshot: no cache test carries an older one). The model must outlive it;
// needs the context it was first called in to be current.
class PortraitRenderer {
 public:
  explicit PortraitRenderer(const Model& model);
  ~PortraitRenderer();
  PortraitRenderer(const PortraitRenderer&) = delete;
  PortraitRenderer& operator=(const PortraitRenderer&) = delete;

  Result<Image> render(const PortraitOptions& options);

  // How many times the renderer and target were made (1 for a run of pictures of one size).
  int setups() const { return setups_; }

 private:
  struct State;
  const Model& model_;
  std::unique_ptr<State> state_;
  int setups_ = 0;
};

}  // namespace bb::runtime
