// A headless OpenGL 4.5 core context through EGL, for our tools and tests (a game brings its own
// context). Tries the EGL device platform (NVIDIA, and Mesa's software device), then Mesa's
// surfaceless platform (llvmpipe), then the default display. BB_EGL_PLATFORM=device|surfaceless
// forces one.
#pragma once

#include <memory>
#include <string>

#include "bb/result.h"

namespace bb::runtime {

class HeadlessContext {
 public:
  // Creates a context and makes it current on this thread. The error says why when EGL or the
  // driver cannot give a 4.5 core context (tests skip with that reason).
  static Result<std::unique_ptr<HeadlessContext>> create();
  ~HeadlessContext();
  HeadlessContext(const HeadlessContext&) = delete;
  HeadlessContext& operator=(const HeadlessContext&) = delete;

  void make_current();
  // "platform: GL_RENDERER (GL_VERSION)", e.g. "surfaceless: llvmpipe (LLVM 15.0.6, 256 bits) (4.5 (Core Profile) Mesa 22.3.6)".
  const std::string& description() const { return description_; }

 private:
  HeadlessContext() = default;
  void* display_ = nullptr;
  void* context_ = nullptr;
  std::string description_;
};

}  // namespace bb::runtime
