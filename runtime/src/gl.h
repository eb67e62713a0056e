// OpenGL 4.5 core entry points: Debian's libOpenGL (glvnd) exports them all when prototypes are
// asked for, so no loader is needed. Private to the runtime's sources.
#pragma once

#ifndef GL_GLEXT_PROTOTYPES
#define GL_GLEXT_PROTOTYPES 1
#endif
#include <GL/glcorearb.h>
