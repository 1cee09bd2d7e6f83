// OpenGL 3.3 core declarations from the system headers, resolved at link time (libGL for the
// window, libOSMesa for the offscreen tests), so no loader is needed. The ImGui OpenGL3 backend
// is compiled with this header forced in (IMGUI_IMPL_OPENGL_LOADER_CUSTOM).
#pragma once

#ifndef GL_GLEXT_PROTOTYPES
#define GL_GLEXT_PROTOTYPES 1
#endif
#include <GL/gl.h>
#include <GL/glext.h>
