#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include <EGL/egl.h>
#include <EGL/eglext.h>

#include "bb/runtime/headless.h"
#include "gl.h"

namespace bb::runtime {

namespace {

bool has_ext(const char* list, const char* name) {
  if (!list) return false;
  const std::size_t n = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)); p += n)
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  return false;
}

struct Attempt {
  std::string name;
  EGLDisplay display;
};

std::vector<Attempt> displays(std::string* why) {
  std::vector<Attempt> out;
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  const char* force = std::getenv("BB_EGL_PLATFORM");
  std::string want = force ? force : "";
  auto get_platform_display =
      reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
  if ((want.empty() || want == "device") && has_ext(client, "EGL_EXT_platform_device") && get_platform_display) {
    auto query = reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
    auto query_string = reinterpret_cast<PFNEGLQUERYDEVICESTRINGEXTPROC>(eglGetProcAddress("eglQueryDeviceStringEXT"));
    EGLDeviceEXT devs[16];
    EGLint n = 0;
    if (query && query(16, devs, &n)) {
      // Hardware devices first; Mesa's software device (EGL_MESA_device_software) last.
      std::vector<EGLDeviceEXT> hw, sw;
      for (EGLint i = 0; i < n; ++i) {
        const char* ext = query_string ? query_string(devs[i], EGL_EXTENSIONS) : nullptr;
        (has_ext(ext, "EGL_MESA_device_software") ? sw : hw).push_back(devs[i]);
      }
      for (auto* list : {&hw, &sw})
        for (EGLDeviceEXT d : *list) {
          EGLDisplay dpy = get_platform_display(EGL_PLATFORM_DEVICE_EXT, d, nullptr);
          if (dpy != EGL_NO_DISPLAY) out.push_back({list == &hw ? "device" : "device (software)", dpy});
        }
    }
  }
  if ((want.empty() || want == "surfaceless") && has_ext(client, "EGL_MESA_platform_surfaceless") && get_platform_display) {
    EGLDisplay dpy = get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    if (dpy != EGL_NO_DISPLAY) out.push_back({"surfaceless", dpy});
  }
  if (want.empty()) {
    EGLDisplay dpy = eglGetDisplay(EGL_DEFAULT_DISPLAY);
    if (dpy != EGL_NO_DISPLAY) out.push_back({"default", dpy});
  }
  if (out.empty()) *why = "no EGL display (client extensions: " + std::string(client ? client : "none") + ")";
  return out;
}

}  // namespace

Result<std::unique_ptr<HeadlessContext>> HeadlessContext::create() {
  std::string why;
  auto attempts = displays(&why);
  for (const Attempt& a : attempts) {
    EGLint major = 0, minor = 0;
    if (!eglInitialize(a.display, &major, &minor)) {
      why += a.name + ": eglInitialize failed; ";
      continue;
    }
    if (!eglBindAPI(EGL_OPENGL_API)) {
      why += a.name + ": no desktop OpenGL; ";
      eglTerminate(a.display);
      continue;
    }
    // eglChooseConfig defaults to window surfaces, which headless displays lack: ask for
    // pbuffer configs, then any surface type, then no config at all (EGL_KHR_no_config_context).
    EGLConfig cfg = nullptr;
    EGLint ncfg = 0;
    const EGLint surface_types[] = {EGL_PBUFFER_BIT, 0};
    for (EGLint st : surface_types) {
      const EGLint cfg_attr[] = {EGL_SURFACE_TYPE, st, EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
      if (eglChooseConfig(a.display, cfg_attr, &cfg, 1, &ncfg) && ncfg >= 1) break;
      cfg = nullptr;
    }
    if (!cfg && !has_ext(eglQueryString(a.display, EGL_EXTENSIONS), "EGL_KHR_no_config_context")) {
      why += a.name + ": no OpenGL config; ";
      eglTerminate(a.display);
      continue;
    }
    const EGLint ctx_attr[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5, EGL_CONTEXT_OPENGL_PROFILE_MASK,
                               EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
    EGLContext ctx = eglCreateContext(a.display, cfg, EGL_NO_CONTEXT, ctx_attr);
    if (ctx == EGL_NO_CONTEXT) {
      why += a.name + ": no OpenGL 4.5 core context; ";
      eglTerminate(a.display);
      continue;
    }
    if (!eglMakeCurrent(a.display, EGL_NO_SURFACE, EGL_NO_SURFACE, ctx)) {
      why += a.name + ": cannot make the context current without a surface; ";
      eglDestroyContext(a.display, ctx);
      eglTerminate(a.display);
      continue;
    }
    std::unique_ptr<HeadlessContext> h(new HeadlessContext());
    h->display_ = a.display;
    h->context_ = ctx;
    const char* r = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
    const char* v = reinterpret_cast<const char*>(glGetString(GL_VERSION));
    h->description_ = a.name + ": " + (r ? r : "?") + " (" + (v ? v : "?") + ")";
    return h;
  }
  return Error{"", "EGL", "no headless OpenGL 4.5 context: " + (why.empty() ? std::string("no display") : why)};
}

HeadlessContext::~HeadlessContext() {
  if (display_) {
    eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    if (context_) eglDestroyContext(display_, context_);
    eglTerminate(display_);
  }
}

void HeadlessContext::make_current() { eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, context_); }

}  // namespace bb::runtime
