// One headless GL context for a test binary's rendering tests (made current once, on first use),
// and REQUIRE_GL(), which skips a test, saying why, where EGL gives none.
#pragma once

#include <cstdio>
#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "bb/runtime/headless.h"

namespace bb::test {

inline std::string& context_error() {
  static std::string why;
  return why;
}

inline runtime::HeadlessContext* context() {
  static std::unique_ptr<runtime::HeadlessContext> ctx;
  static bool tried = false;
  if (!tried) {
    tried = true;
    auto r = runtime::HeadlessContext::create();
    if (r) {
      ctx = std::move(*r);
      std::printf("GL context: %s\n", ctx->description().c_str());
    } else {
      context_error() = r.error().message();
    }
  }
  return ctx.get();
}

}  // namespace bb::test

#define REQUIRE_GL()                                                                        \
  if (!::bb::test::context()) GTEST_SKIP() << "no headless OpenGL context: " << ::bb::test::context_error()
