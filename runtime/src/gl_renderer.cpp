// GL 4.5 back end of the runtime: GPU skinning from baked clips, instanced geometry, the
// snapshot passes into the shared atlas, and the camera-facing impostor quads.
#include <algorithm>
#include <array>
#include <cassert>
#include <cstddef>
#include <cstdlib>
#include <cmath>
#include <cstring>
#include <initializer_list>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include <glm/gtc/type_ptr.hpp>

#include "bb/runtime/renderer.h"
#include "depth_order.h"
#include "impostor_layers.h"
#include "gl.h"

namespace bb::runtime {

namespace {

const char* kCommon = R"(#version 450 core
layout(binding = 0) uniform samplerBuffer u_palette;  // 3 RGBA32F texels per palette entry per frame
uniform int u_palette_size;
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec3 a_nrm;
layout(location = 2) in vec2 a_uv;
layout(location = 3) in uvec4 a_joints;
layout(location = 4) in vec4 a_weights;
layout(location = 5) in vec4 i_pos_yaw;
layout(location = 6) in vec4 i_anim;  // scale, row f0, row f1, blend
out vec3 v_nrm;
out vec2 v_uv;
#ifdef BB_COLORED
layout(location = 15) in vec4 a_color;  // COLOR_0
out vec4 v_color;
#endif
mat3x4 rows(uint j, int frame) {
  int base = (frame * u_palette_size + int(j)) * 3;
  return mat3x4(texelFetch(u_palette, base), texelFetch(u_palette, base + 1), texelFetch(u_palette, base + 2));
}
// Skinned, placed vertex in world space; normal in v_nrm.
vec3 skin_world() {
  int r0 = int(i_anim.y), r1 = int(i_anim.z);
  float b = i_anim.w;
  mat3x4 m = mat3x4(0.0);
  for (int k = 0; k < 4; ++k) {
    float w = a_weights[k];
    if (w > 0.0) m += w * ((1.0 - b) * rows(a_joints[k], r0) + b * rows(a_joints[k], r1));
  }
  vec3 p = vec4(a_pos, 1.0) * m;
  vec3 n = vec4(a_nrm, 0.0) * m;
  float c = cos(i_pos_yaw.w), s = sin(i_pos_yaw.w);
  p *= i_anim.x;
  v_nrm = vec3(c * n.x + s * n.z, n.y, -s * n.x + c * n.z);
  v_uv = a_uv;
#ifdef BB_COLORED
  v_color = a_color;
#endif
  return i_pos_yaw.xyz + vec3(c * p.x + s * p.z, p.y, -s * p.x + c * p.z);
}
)";

const char* kGeometryVs = R"(
uniform mat4 u_viewproj;
void main() { gl_Position = u_viewproj * vec4(skin_world(), 1.0); }
)";

// Section 4.2: orthographic snapshot camera, mapped into the character's window of the page.
const char* kSnapshotVs = R"(
layout(location = 7) in vec4 i_ho_half;
layout(location = 8) in vec4 i_uo_dist;
layout(location = 9) in vec4 i_vo;
layout(location = 10) in vec4 i_ta;
layout(location = 11) in vec4 i_window;
layout(location = 12) in vec4 i_rect;
layout(location = 13) in vec4 i_offset;  // off-axis window (aligned snapshots), metres
out float gl_ClipDistance[4];
// The level's vertex count: vertices from there on are body parts' caps (PartIndices::cap_vertices).
uniform int u_first_cap = 0x7fffffff;
flat out float v_cap;
#ifdef BB_NORMALS
flat out vec3 v_ho, v_uo, v_vo;  // the snapshot camera's frame (world, unit)
#else
flat out vec3 v_vo;  // the snapshot camera's view direction (world, unit)
#endif
#ifdef BB_OFFSET
out float v_offset;  // offset from the card plane along Vo, in half sizes (linear: exact when interpolated)
#endif
void main() {
  vec3 d = skin_world() - i_ta.xyz;
  float h = i_ho_half.w, r = i_ta.w, dist = i_uo_dist.w;
  vec2 xy = vec2(dot(d, i_ho_half.xyz), dot(d, i_uo_dist.xyz)) / h;
  float depth = dot(d, i_vo.xyz);
  vec4 c;
  if (i_vo.w > 0.5) {  // perspective from the eye: w = distance along Vo
    float z = dist + depth;
    float n = max(dist - r, 0.01 * dist), f = dist + r;
    c = vec4(xy * dist - i_offset.xy * (depth / h), ((f + n) * z - 2.0 * f * n) / (f - n), z);
  } else {
    c = vec4(xy, clamp(depth / r, -1.0, 1.0), 1.0);
  }
  gl_Position = vec4(i_window.xy * c.w + c.xy * i_window.z, c.z, c.w);
#ifdef BB_OFFSET
  v_offset = depth / h;
#endif
#ifdef BB_NORMALS
  v_ho = i_ho_half.xyz;
  v_uo = i_uo_dist.xyz;
#endif
  v_vo = i_vo.xyz;
  v_cap = gl_VertexID >= u_first_cap ? 1.0 : 0.0;
#ifdef BB_LAYERED
  gl_Layer = int(i_window.w);
#endif
  // Only inside the part of the window that was cleared.
  gl_ClipDistance[0] = c.x - i_rect.x * c.w;
  gl_ClipDistance[1] = i_rect.z * c.w - c.x;
  gl_ClipDistance[2] = c.y - i_rect.y * c.w;
  gl_ClipDistance[3] = i_rect.w * c.w - c.y;
}
)";

// One program per kind of material (ShadeProgram): BB_TEXTURED fetches the base colour texture,
// BB_MASKED discards below the alpha cutoff, and with u_blend 1 (alpha BLEND, cutoff 0) writes the
// colour premultiplied by its alpha instead of opaque. llvmpipe runs a fetch that a uniform makes useless
// (a 1x1 white texture), and a shader that can discard loses the early depth test; the plain
// variant has neither (flow test bed, our body untextured but for its lowest level, 4x MSAA:
// the geometry frame about 9 % faster).
const char* kShadeFs = R"(#version 450 core
layout(binding = 1) uniform sampler2D u_tex;
uniform vec4 u_color;
uniform float u_cutoff;  // < 0: opaque
uniform vec3 u_light;    // unit, world, towards the light
uniform float u_lit;     // 1: lit; 0: unlit (KHR_materials_unlit: the colour as is)
uniform vec3 u_emissive; // glTF emissiveFactor: light of its own, added after the shading
#ifdef BB_MASKED
uniform float u_blend;   // 1: alpha BLEND (premultiplied output); 0: opaque
#endif
in vec3 v_nrm;
in vec2 v_uv;
#ifdef BB_COLORED
in vec4 v_color;
#endif
layout(location = 0) out vec4 o_color;
#ifdef BB_NORMALS
// Relit snapshots (ImpostorConfig::relight): the albedo, and the normal in the snapshot camera's
// frame (Ho, Uo, Vo), encoded n * 0.5 + 0.5, and in its alpha whether the texel is lit (u_lit); the
// impostor shader lights them as drawn.
flat in vec3 v_ho, v_uo, v_vo;
layout(location = 1) out vec4 o_normal;
#elif defined(BB_SNAPSHOT)
flat in vec3 v_vo;
#endif
#ifdef BB_SNAPSHOT
// 1 while a body part's snapshot is drawn: a back face of a double-sided material (the others are
// culled, their cuts closed by caps) seen through the part's cut stands in for the neighbouring
// surface that continues it there, the near side of the tube, so it is lit with its normal mirrored
// across the view direction (the near side's normal where the part is a cylinder about the line of
// sight's normal) instead of reversed, which turns its side away from the light (dark slivers at
// the joints).
uniform float u_cut;
// 1 on a body part's cap (PartIndices::Range::caps): it stands for the surface that continues the
// part through its cut, whose normal, seen from the snapshot camera, is the cap's interpolated one
// (outward across the opening, not unit) turned towards the camera: its part across the view kept,
// the rest along the view.
flat in float v_cap;
#endif
#ifdef BB_OFFSET
// Depth-corrected part cards (ImpostorConfig::parallax_cards): the texel's surface offset from the
// card plane, masked by its coverage (offset, 1), so that one bilinear fetch gives the impostor
// shader the covered texels' weighted mean (x / y).
in float v_offset;
layout(location = 2) out vec2 o_offset;
#endif
void main() {
#ifdef BB_TEXTURED
  vec4 c = u_color * texture(u_tex, v_uv);
#else
  vec4 c = u_color;
#endif
#ifdef BB_COLORED
  c *= v_color;
#endif
  float a = 1.0;  // premultiplied, opaque
#ifdef BB_MASKED
  if (c.a < u_cutoff) discard;
  a = mix(1.0, clamp(c.a, 0.0, 1.0), u_blend);
#endif
  vec3 n = normalize(v_nrm);
#ifdef BB_SNAPSHOT
  if (v_cap > 0.5) {
    vec3 across = v_nrm - dot(v_nrm, v_vo) * v_vo;
    float a2 = dot(across, across);
    n = a2 < 1.0 ? across - sqrt(1.0 - a2) * v_vo : across * inversesqrt(a2);
  } else if (!gl_FrontFacing) {
    n = u_cut > 0.5 ? reflect(n, v_vo) : -n;
  }
#else
  if (!gl_FrontFacing) n = -n;
#endif
#ifdef BB_NORMALS
  // The impostor shader lights a texel as colour * mix(1, light, share): with an emissive colour
  // the texel holds albedo + emission and the lit share is the albedo's part of its luminance, so a
  // texel of emission alone stays as bright whatever the light (exact for grey, else close).
  const vec3 lum = vec3(0.2126, 0.7152, 0.0722);
  vec3 ce = c.rgb + u_emissive;
  float all_light = dot(ce, lum);
  float share = all_light > 0.0 ? dot(c.rgb, lum) / all_light : 1.0;
  o_color = vec4(ce * a, a);
  o_normal = vec4(vec3(dot(n, v_ho), dot(n, v_uo), dot(n, v_vo)) * 0.5 + 0.5, u_lit * share) * a;
#else
  float l = mix(1.0, 0.35 + 0.65 * max(dot(n, u_light), 0.0), u_lit);
  o_color = vec4((c.rgb * l + u_emissive) * a, a);
#endif
#ifdef BB_OFFSET
  o_offset = vec2(v_offset, 1.0);
#endif
}
)";

const char* kClearVs = R"(#version 450 core
layout(location = 11) in vec4 i_window;
layout(location = 12) in vec4 i_rect;
out float gl_ClipDistance[4];
void main() {
  vec2 c = mix(i_rect.xy, i_rect.zw, vec2(gl_VertexID & 1, gl_VertexID >> 1));
  gl_Position = vec4(i_window.xy + c * i_window.z, 1.0, 1.0);
#ifdef BB_LAYERED
  gl_Layer = int(i_window.w);
#endif
  for (int k = 0; k < 4; ++k) gl_ClipDistance[k] = 1.0;
}
)";

const char* kClearFs = R"(#version 450 core
layout(location = 0) out vec4 o_color;
layout(location = 1) out vec4 o_normal;  // relit snapshots' normals (no buffer otherwise)
layout(location = 2) out vec4 o_offset;  // depth-corrected cards' plane offsets (no buffer otherwise)
void main() {
  o_color = vec4(0.0);
  o_normal = vec4(0.0);
  o_offset = vec4(0.0);
}
)";

// Multisampled snapshots: the scratch page's samples averaged into the atlas (premultiplied, so
// alpha is the texel's coverage), over the same rects as the clear.
const char* kResolveFs = R"(#version 450 core
layout(binding = 3) uniform sampler2DMS u_scratch;
uniform int u_samples;
layout(location = 0) out vec4 o_color;
void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec4 sum = vec4(0.0);
  for (int k = 0; k < u_samples; ++k) sum += texelFetch(u_scratch, p, k);
  o_color = sum / float(u_samples);
}
)";

const char* kBillboardVs = R"(#version 450 core
#ifdef BB_PULL
layout(binding = 7) uniform samplerBuffer u_quads;  // 7 RGBA32F texels per quad (BillboardGpu)
vec4 i_ta_half, i_uv, i_layer, i_rect, i_axis_x, i_axis_y, i_snap;
int corner;
void pull() {
  int b = (gl_VertexID >> 2) * 7;
  i_ta_half = texelFetch(u_quads, b);
  i_uv = texelFetch(u_quads, b + 1);
  i_layer = texelFetch(u_quads, b + 2);
  i_rect = texelFetch(u_quads, b + 3);
  i_axis_x = texelFetch(u_quads, b + 4);
  i_axis_y = texelFetch(u_quads, b + 5);
  i_snap = texelFetch(u_quads, b + 6);
  corner = gl_VertexID & 3;
}
#else
layout(location = 0) in vec4 i_ta_half;
layout(location = 1) in vec4 i_uv;
layout(location = 2) in vec4 i_layer;
layout(location = 3) in vec4 i_rect;
layout(location = 4) in vec4 i_axis_x;  // part cards (w = 1): half axes, world
layout(location = 5) in vec4 i_axis_y;
layout(location = 6) in vec4 i_snap;  // depth-corrected part cards (z > 0): snapshot eye, radius
int corner;
void pull() { corner = gl_VertexID; }
#endif
uniform mat4 u_viewproj;
uniform vec3 u_eye;
uniform vec3 u_up;
// Quads fitted to the coverage (i_layer.z = 1): the rectangle kCoverageCs found in the window.
layout(std430, binding = 0) readonly buffer Coverage { vec4 covered[]; };
out vec3 v_uvl;
// The quad's texels in the atlas (u0, v0, u1, v1), half a texel in from its edges: a tap beside
// the quad reads its edge texel, never a neighbouring window's (whose snapshot may reach its own
// border: a part that fills its window) nor texels of the window that this snapshot did not clear.
// Unclamped, the taps of the pixels at a quad's edge brought in dashes of other characters' parts
// (flow test bed, part cards at 8 degrees: 12 and 23 impostor pixels more than 2 pixels from any
// geometry pixel in two frames, none clamped; PSNR 26.205 -> 26.211 dB; the card pass's wait for
// llvmpipe 2.41 -> 2.66 ms, medians of five alternated runs, inside this machine's noise).
flat out vec4 v_clamp;
uniform float u_half_texel;  // half an atlas texel: 0.5 / the page size (ImpostorConfig::page_size)
#ifdef BB_CARD_DEPTH
// Depth-corrected part cards (the program with BB_CARD_DEPTH, where i_snap.z > 0).
out vec2 v_c;          // point of the card plane, window units
flat out vec3 v_eye;   // the eye in the card's frame (window units; z along the snapshot's Vo)
flat out vec4 v_snap;  // i_snap when corrected, else 0
flat out vec4 v_rect;  // the part of the window with snapshot texels
flat out vec4 v_uvbox;
flat out vec2 v_eye_clip;  // the eye's clip z and w: the depth of a point on a pixel's eye ray
#endif
#ifdef BB_RELIGHT
flat out mat3 v_frame;  // the quad's Ho, Uo, Vo now (world, unit): relit snapshots' normals to world
#endif
void main() {
  pull();
  vec4 r = i_rect;
  if (i_layer.z > 0.5) {
    vec4 f = covered[int(i_layer.y)];
    r = vec4(max(r.xy, f.xy), min(r.zw, f.zw));
    if (any(greaterThanEqual(r.xy, r.zw))) r = vec4(0.0);  // nothing covered: no area
  }
#ifdef BB_CARD_DEPTH
  v_rect = r;
  v_uvbox = i_uv;
  v_snap = vec4(0.0);
  v_eye = vec3(0.0);
  v_eye_clip = (u_viewproj * vec4(u_eye, 1.0)).zw;
  if (i_axis_x.w > 0.5 && i_snap.z > 0.0 && r.x < r.z) {
    // The card's frame: Ho, Uo, Vo = Uo x Ho, lengths in half sizes.
    float hl = length(i_axis_x.xyz);
    vec3 ho = i_axis_x.xyz / hl, uo = normalize(i_axis_y.xyz), vo = normalize(cross(uo, ho));
    vec3 d = (u_eye - i_ta_half.xyz) / hl;
    vec3 e = vec3(dot(d, ho), dot(d, uo), dot(d, vo));
    float ez = -e.z;
    if (ez > 2.0 * i_snap.w) {
      // The quad is not widened to where the snapshot's surface appears from this eye: tried
      // (each corner's snapshot ray at both ends of the covered depth range), it cost 14 % of the
      // card pass on llvmpipe for no measured gain (flow test bed, 8 and 17 degrees: PSNR +0.02
      // and +0.03 dB without it; the fitted quad's margin holds the shift).
      v_snap = i_snap;
      v_eye = e;
    }
  }
#endif
  vec2 c = mix(r.xy, r.zw, vec2(corner & 1, corner >> 1));
#ifdef BB_CARD_DEPTH
  v_c = c;
#endif
  vec3 ta = i_ta_half.xyz;
  vec3 p;
  if (i_axis_x.w > 0.5) {
    p = ta + c.x * i_axis_x.xyz + c.y * i_axis_y.xyz;
#ifdef BB_RELIGHT
    // The card's carried axes: its snapshot's Ho and Uo turned with the bone since.
    vec3 ho = normalize(i_axis_x.xyz), uo = normalize(i_axis_y.xyz);
    v_frame = mat3(ho, uo, normalize(cross(uo, ho)));
#endif
  } else {
    vec3 vo = normalize(ta - u_eye);
    vec3 h = cross(vo, u_up);
    if (length(h) < 1e-6) h = cross(vo, vec3(0.0, 0.0, 1.0));
    vec3 ho = normalize(h);
    vec3 uo = cross(ho, vo);
    p = ta + i_ta_half.w * (c.x * ho + c.y * uo);
#ifdef BB_RELIGHT
    v_frame = mat3(ho, uo, vo);
#endif
  }
  gl_Position = u_viewproj * vec4(p, 1.0);
  v_uvl = vec3(mix(i_uv.xy, i_uv.zw, c * 0.5 + 0.5), i_layer.x);
  // The texels the quad covers, half a texel in: every tap is clamped to them (v_clamp).
  vec2 h = vec2(u_half_texel);
  vec2 q0 = mix(i_uv.xy, i_uv.zw, r.xy * 0.5 + 0.5), q1 = mix(i_uv.xy, i_uv.zw, r.zw * 0.5 + 0.5);
  v_clamp = vec4(min(q0, q1) + h, max(q0, q1) - h);
}
)";

// The window holds the snapshot at about 2 texels per screen pixel (ImpostorConfig::
// texels_per_pixel), premultiplied. Taps placed from the screen-space derivatives of the texture
// coordinates look the window up inside the pixel: at the framebuffer's own sample positions
// (BB_PER_SAMPLE: each sample covered where the window is at least half covered), or at the
// standard 4x pattern, averaged (coverage as alpha).
// One program per edge mode and tap count (BB_EDGES, BB_TAPS): llvmpipe runs both sides of a
// branch on a uniform, so a mode chosen by uniform paid for every other mode's taps (flow test bed,
// SimpleSkin, nothing refreshed: the quad pass 8 % slower with two spare taps, twice as slow with
// five).
//   BB_EDGES 0: alpha test, 1: premultiplied blending, 2: alpha to coverage, 4: one tap
//   BB_TAPS 4: the pixel's coverage from four taps; 1: one tap (the texels hold it)
const char* kBillboardFs = R"(#version 450 core
layout(binding = 2) uniform sampler2DArray u_atlas;
uniform int u_samples;
uniform vec2 u_sample_pos[16];  // offsets from the pixel centre, pixels
in vec3 v_uvl;
#ifdef BB_CARD_DEPTH
// The snapshots' plane offsets, masked by coverage (kShadeFs's o_offset), filtered bilinearly.
layout(binding = 4) uniform sampler2DArray u_offset;
layout(binding = 6) uniform sampler2DArray u_offset_wide;  // the same at a quarter of the resolution (kCoverageCs)
in vec2 v_c;
flat in vec3 v_eye;
flat in vec4 v_snap;
flat in vec4 v_rect;
flat in vec4 v_uvbox;
flat in vec2 v_eye_clip;
uniform int u_depth_pass;  // 1: blended cards' depth pass (opaque texels, no colour)
#endif
flat in vec4 v_clamp;  // kBillboardVs's: the quad's texels, half a texel in
layout(location = 0) out vec4 o_color;
#ifdef BB_RELIGHT
// Relit snapshots: the atlas holds the albedo and this the normals (premultiplied like the colour,
// in the snapshot's frame, encoded n * 0.5 + 0.5; alpha: the share of lit texels, unlit materials
// being 0), lit here in the quad's frame of now, so a card turned by its bone since its snapshot is
// shaded as it now lies under the light.
layout(binding = 5) uniform sampler2DArray u_atlas_normal;
uniform vec3 u_light;  // unit, world, towards the light
flat in mat3 v_frame;
// Premultiplied albedo c and normal code m (the same taps) -> premultiplied lit colour.
vec4 lit(vec4 c, vec4 m) {
  if (c.a <= 0.0) return c;
  vec3 n = v_frame * (m.rgb / c.a * 2.0 - 1.0);
  float len = length(n);
  float l = len > 1e-4 ? 0.35 + 0.65 * max(dot(n / len, u_light), 0.0) : 0.35;
  return vec4(c.rgb * mix(1.0, l, clamp(m.a / c.a, 0.0, 1.0)), c.a);
}
vec4 tap(vec2 uv) {
  vec3 p = vec3(clamp(uv, v_clamp.xy, v_clamp.zw), v_uvl.z);
  return lit(texture(u_atlas, p), texture(u_atlas_normal, p));
}
#else
vec4 tap(vec2 uv) { return texture(u_atlas, vec3(clamp(uv, v_clamp.xy, v_clamp.zw), v_uvl.z)); }
#endif
void main() {
  vec2 dx = dFdx(v_uvl.xy), dy = dFdy(v_uvl.xy);
  vec2 uv0 = v_uvl.xy;
#ifdef BB_CARD_DEPTH
  // Only in the depth-corrected cards' program: a branch that no pixel takes still cost llvmpipe
  // 30 % of the impostor pass (Fox, 20 whole impostors, no refreshes: 3.9 -> 2.6 ms without it).
  gl_FragDepth = gl_FragCoord.z;
  if (v_snap.z > 0.0) {
    // Depth-corrected card: find the window point w whose snapshot surface point lies on this
    // pixel's eye ray. From the plane point c: the surface's offset t at w, the ray's point at
    // that offset, seen from the snapshot's eye on the plane (iterative parallax mapping).
    // The surface's offset t at w: the covered texels' bilinear mean (one fetch of the masked
    // offsets), else the last step's.
    // Only the first step looks further (u_offset_wide) where no covered texel is near: the
    // same PSNR as every step doing so (flow test bed, 8 degrees), one fetch less.
    vec2 c = v_c, s = -v_snap.xy, w = c, x = c;
    float ez = -v_eye.z, dist = v_snap.z, t = 0.0;
    for (int k = 0; k < BB_STEPS; ++k) {
      vec3 p = vec3(mix(v_uvbox.xy, v_uvbox.zw, clamp(w, v_rect.xy, v_rect.zw) * 0.5 + 0.5), v_uvl.z);
      vec2 m = texture(u_offset, p).xy;
      if (k == 0) m = m.y > 0.0 ? m : texture(u_offset_wide, p).xy;
      t = m.y > 0.0 ? m.x / m.y : t;
      x = c + (c - v_eye.xy) * (t / ez);
      w = s + (x - s) * (dist / (dist + t));
    }
    if (any(lessThan(w, v_rect.xy)) || any(greaterThan(w, v_rect.zw))) discard;
    uv0 = mix(v_uvbox.xy, v_uvbox.zw, w * 0.5 + 0.5);
    // The depth of the snapshot surface found on this pixel's ray, so overlapping cards (at the
    // joints) hide each other where their surfaces do. That point is the eye plus (1 + t / ez)
    // times this pixel's plane point, so its clip coordinates are the eye's plus as many times
    // the plane point's less the eye's.
    float wp = 1.0 / gl_FragCoord.w, g = 1.0 + t / ez;
    vec2 zw = v_eye_clip + g * (vec2((2.0 * gl_FragCoord.z - 1.0) * wp, wp) - v_eye_clip);
    gl_FragDepth = clamp(0.5 + 0.5 * zw.x / zw.y, 0.0, 1.0);
  }
#endif
#ifdef BB_PER_SAMPLE
  {
    int mask = 0;
    vec4 sum = vec4(0.0);
    for (int k = 0; k < u_samples; ++k) {
      vec4 t = tap(uv0 + u_sample_pos[k].x * dx + u_sample_pos[k].y * dy);
      if (t.a >= 0.5) {
        mask |= 1 << k;
        sum += t;
      }
    }
    if (mask == 0) discard;
    gl_SampleMask[0] = mask;
    o_color = vec4(sum.rgb / sum.a, 1.0);
  }
#else
#if BB_EDGES == 4
  // One tap at the pixel centre: at one texel per pixel, texels on pixels, an exact copy.
  vec4 t = tap(uv0);
  if (t.a < 0.5) discard;
  o_color = vec4(t.rgb / t.a, 1.0);
#else
#if BB_TAPS == 1
  vec4 c = tap(uv0);
#elif BB_TAPS == 2
  // Two taps on the anti-diagonal, 0.28 pixels from the centre (taps at -+(0.2, -0.2) pixels:
  // the best of fourteen pairs on the flow test bed, every impostor fresh; checked on its four models).
  vec4 c = 0.5 * (tap(uv0 - 0.2 * dx + 0.2 * dy) + tap(uv0 + 0.2 * dx - 0.2 * dy));
#else
  vec4 c = 0.25 * (tap(uv0 - 0.125 * dx - 0.375 * dy) + tap(uv0 + 0.375 * dx - 0.125 * dy) +
                   tap(uv0 - 0.375 * dx + 0.125 * dy) + tap(uv0 + 0.125 * dx + 0.375 * dy));
#endif
#if BB_EDGES == 0
  if (c.a < 0.5) discard;
  o_color = vec4(c.rgb / c.a, 1.0);
#elif BB_EDGES == 2
  // The alpha picks the share of the pixel's samples, so the colour goes in straight (and
  // alpha to one makes the covered samples opaque).
  if (c.a < 1.0 / 255.0) discard;
  o_color = vec4(c.rgb / c.a, c.a);
#else
  if (c.a < 1.0 / 255.0) discard;
#ifdef BB_CARD_DEPTH
  if (u_depth_pass == 1 && c.a < 0.99) discard;  // the depth pass: opaque texels only
#endif
  o_color = c;
#endif
#endif
#endif
}
)";

// Quads fitted to the coverage (ImpostorConfig::fit_quads_to_coverage): per new snapshot (one
// work group), the smallest rectangle of its quad that holds every texel with coverage, widened by
// part.w texels (how far the impostor shader's taps at a pixel beside it reach), in window units;
// an empty snapshot gets an empty rectangle. The planner's quad bounds it. BB_GROUP x BB_GROUP
// invocations (ImpostorConfig::coverage_group: 4 on llvmpipe, 16 on a GPU), each gathering 2x2
// texels a step: on llvmpipe 4x4 took 0.43 ms a frame for the part cards' ~50 new snapshots and
// 0.65 ms for 20 Fox windows, against 0.75 and 1.02 ms with 16x16 invocations fetching a texel
// each; 16x16 with the gathers is the same within the noise there.
//
// With depth-corrected part cards (BB_OFFSETS) the same pass reads the snapshots' masked plane
// offsets instead (their mask is the coverage) and also writes them at a quarter of the resolution
// for each new card snapshot: each texel the mean of 4x4 (masked, like the offsets), so that where
// the 2x2 around a point holds no covered texel the impostor shader finds the surface within about
// four texels with one more fetch, and a silhouette can move outwards as the eye turns (near a
// window's border that reach can take in the next window's texels, as the atlas taps' can). Flow test
// bed, part cards, 8 / 17 / 90 degrees: 26.56 / 24.73 / 20.41 dB with 4x4, 26.56 / 24.67 / 20.17
// with 2x2 (the four gathers around the point that it replaced: 26.56 / 24.73 / 20.47).
const char* kCoverageCs = R"(#version 450 core
layout(local_size_x = BB_GROUP, local_size_y = BB_GROUP) in;
layout(binding = 2) uniform sampler2DArray u_atlas;
layout(std430, binding = 0) writeonly buffer Coverage { vec4 covered[]; };
struct Snapshot { vec4 instance[2], ho_half, uo_dist, vo, ta, window, rect, offset, part, quad; };  // SnapshotGpu
layout(std430, binding = 1) readonly buffer Snapshots { Snapshot snapshots[]; };
uniform float u_page;  // page size, texels
shared int lo_x, lo_y, hi_x, hi_y;
#ifdef BB_OFFSETS
layout(binding = 4) uniform sampler2DArray u_offset;
layout(binding = 0, rg16f) uniform writeonly image2DArray u_wide;
ivec2 a = ivec2(1 << 30), b = ivec2(-(1 << 30)), t0, t1;
// Texel t, covered or not (m > 0), into the covered rectangle if it lies in [t0, t1].
void cover(ivec2 t, float m) {
  if (m > 0.0 && all(greaterThanEqual(t, t0)) && all(lessThanEqual(t, t1))) {
    a = min(a, t);
    b = max(b, t);
  }
}
#endif
void main() {
  Snapshot s = snapshots[gl_WorkGroupID.x];
#ifdef BB_OFFSETS
  bool wide = s.part.x >= 0.0 && s.vo.w > 0.5;  // a perspective card snapshot
  if (s.part.z < 0.5 && !wide) return;  // the whole work group: nothing to do
#else
  if (s.part.z < 0.5) return;  // the whole work group: not fitted
#endif
  if (gl_LocalInvocationIndex == 0u) {
    lo_x = 1 << 30;
    lo_y = 1 << 30;
    hi_x = -(1 << 30);
    hi_y = -(1 << 30);
  }
  barrier();
  float size = s.window.z * u_page;
  vec2 origin = (s.window.xy - s.window.z + 1.0) * 0.5 * u_page;  // window's lower-left texel
  ivec2 lo = ivec2(origin), hi = ivec2(origin + size) - 1;
#ifndef BB_OFFSETS
  ivec2 t0, t1, a = ivec2(1 << 30), b = ivec2(-(1 << 30));
#endif
  t0 = clamp(ivec2(floor(origin + (s.quad.xy + 1.0) * 0.5 * size)), lo, hi);
  t1 = clamp(ivec2(ceil(origin + (s.quad.zw + 1.0) * 0.5 * size)) - 1, lo, hi);
  float layer = s.window.w;
#ifdef BB_OFFSETS
  // Blocks of 4x4 texels (the wide texels): over the quad and a block more each side where the
  // wide texels are wanted, else over the quad. Windows lie on multiples of 4 texels.
  ivec2 w0 = t0 >> 2, w1 = t1 >> 2;
  if (wide) {
    w0 = max(w0 - 1, lo >> 2);
    w1 = min(w1 + 1, hi >> 2);
  }
  if (s.part.z < 0.5) t1 = t0 - 1;  // not fitted: no texel counts
  vec2 inv = 1.0 / vec2(textureSize(u_offset, 0).xy);
  for (int by = w0.y + int(gl_LocalInvocationID.y); by <= w1.y; by += BB_GROUP)
    for (int bx = w0.x + int(gl_LocalInvocationID.x); bx <= w1.x; bx += BB_GROUP) {
      vec2 sum = vec2(0.0);
      for (int j = 0; j < 4; j += 2)
        for (int i = 0; i < 4; i += 2) {
          // One gather each of the masks and the masked offsets of 2x2 texels: x: (0,1), y: (1,1),
          // z: (1,0), w: (0,0).
          ivec2 q = 4 * ivec2(bx, by) + ivec2(i, j);
          vec3 p = vec3(vec2(q + 1) * inv, layer);
          vec4 m = textureGather(u_offset, p, 1);
          sum += vec2(dot(textureGather(u_offset, p, 0), vec4(1.0)), dot(m, vec4(1.0)));
          cover(q + ivec2(0, 1), m.x);
          cover(q + ivec2(1, 1), m.y);
          cover(q + ivec2(1, 0), m.z);
          cover(q, m.w);
        }
      if (wide) imageStore(u_wide, ivec3(bx, by, int(layer)), vec4(sum / 16.0, 0.0, 0.0));
    }
#else
  // 2x2 texels per step: one gather of their alphas (x: (0,1), y: (1,1), z: (1,0), w: (0,0)),
  // texels past t1 (the next window's) masked out. A quarter of the fetches of one per texel.
  vec2 inv = 1.0 / vec2(textureSize(u_atlas, 0).xy);
  for (int y = t0.y + 2 * int(gl_LocalInvocationID.y); y <= t1.y; y += 2 * BB_GROUP)
    for (int x = t0.x + 2 * int(gl_LocalInvocationID.x); x <= t1.x; x += 2 * BB_GROUP) {
      bvec4 c = greaterThan(textureGather(u_atlas, vec3(vec2(x + 1, y + 1) * inv, layer), 3), vec4(0.0));
      bool in_x = x + 1 <= t1.x, in_y = y + 1 <= t1.y;
      c = bvec4(c.x && in_y, c.y && in_x && in_y, c.z && in_x, c.w);
      if (any(c)) {
        a = min(a, ivec2(c.w || c.x ? x : x + 1, c.w || c.z ? y : y + 1));
        b = max(b, ivec2(c.y || c.z ? x + 1 : x, c.x || c.y ? y + 1 : y));
      }
    }
#endif
  if (a.x <= b.x) {
    atomicMin(lo_x, a.x);
    atomicMin(lo_y, a.y);
    atomicMax(hi_x, b.x);
    atomicMax(hi_y, b.y);
  }
  barrier();
  if (gl_LocalInvocationIndex == 0u && s.part.z > 0.5) {
    vec4 r = vec4(1.0, 1.0, -1.0, -1.0);  // empty
    if (lo_x <= hi_x) {
      // Texels [lo, hi + 1) and the taps' reach (part.w texels) each side, as window units.
      vec2 p0 = (vec2(lo_x, lo_y) - s.part.w - origin) / size * 2.0 - 1.0;
      vec2 p1 = (vec2(hi_x, hi_y) + 1.0 + s.part.w - origin) / size * 2.0 - 1.0;
      r = vec4(p0, p1);
    }
    covered[int(s.part.y)] = r;
  }
}
)";

// With ARB_shader_viewport_layer_array the vertex shader picks the atlas page (gl_Layer), so all
// the snapshots of a frame go out in one pass over a layered framebuffer.
std::string layered(const std::string& src) {
  const std::string v = "#version 450 core\n";
  if (src.compare(0, v.size(), v) != 0) return src;
  return v + "#extension GL_ARB_shader_viewport_layer_array : require\n#define BB_LAYERED 1\n" + src.substr(v.size());
}

// `src` with "#define name value" after its #version line (a shader variant).
std::string with_define(std::string src, const char* name, int value = 1) {
  src.insert(src.find('\n') + 1, std::string("#define ") + name + " " + std::to_string(value) + "\n");
  return src;
}

// ImpostorConfig::coverage_group as used: 4, 8 or 16 (0: by the rasterizer).
int coverage_group_size(int asked, bool software) {
  if (asked <= 0) return software ? 4 : 16;
  return asked <= 4 ? 4 : asked <= 8 ? 8 : 16;
}

bool has_gl_extension(const char* name) {
  GLint n = 0;
  glGetIntegerv(GL_NUM_EXTENSIONS, &n);
  for (GLint i = 0; i < n; ++i)
    if (const char* e = reinterpret_cast<const char*>(glGetStringi(GL_EXTENSIONS, static_cast<GLuint>(i)));
        e && std::strcmp(e, name) == 0)
      return true;
  return false;
}

Result<GLuint> compile(GLenum type, const std::string& src, const char* what) {
  GLuint s = glCreateShader(type);
  const char* p = src.c_str();
  glShaderSource(s, 1, &p, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[4096] = {};
    glGetShaderInfoLog(s, sizeof log, nullptr, log);
    glDeleteShader(s);
    return Error{"", what, std::string("shader does not compile: ") + log};
  }
  return s;
}

// Links the compiled `shaders` into a program (and deletes them).
Result<GLuint> link(std::initializer_list<GLuint> shaders, const char* what) {
  GLuint p = glCreateProgram();
  for (GLuint sh : shaders) glAttachShader(p, sh);
  glLinkProgram(p);
  for (GLuint sh : shaders) glDeleteShader(sh);
  GLint ok = 0;
  glGetProgramiv(p, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[4096] = {};
    glGetProgramInfoLog(p, sizeof log, nullptr, log);
    glDeleteProgram(p);
    return Error{"", what, std::string("program does not link: ") + log};
  }
  return p;
}

Result<GLuint> program(const std::string& vs, const std::string& fs, const char* what) {
  auto v = compile(GL_VERTEX_SHADER, vs, what);
  if (!v) return v.error();
  auto f = compile(GL_FRAGMENT_SHADER, fs, what);
  if (!f) {
    glDeleteShader(*v);
    return f.error();
  }
  return link({*v, *f}, what);
}

// A buffer that grows and is rewritten every frame.
struct StreamBuffer {
  GLuint id = 0;
  std::size_t capacity = 0;
  void reserve(std::size_t bytes) {
    if (bytes <= capacity) return;
    capacity = std::max(bytes, capacity * 2);
    glNamedBufferData(id, static_cast<GLsizeiptr>(capacity), nullptr, GL_STREAM_DRAW);
  }
  void upload(const void* data, std::size_t bytes) {
    if (bytes == 0) return;
    reserve(bytes);
    glNamedBufferSubData(id, 0, static_cast<GLsizeiptr>(bytes), data);
  }
  // fill(p) writes the first `bytes` at p, straight into the buffer (mapped, its old contents
  // given up, so that a driver may hand it new storage rather than wait for draws that still read
  // the old): one pass over the data where gathering into a scratch list and uploading that
  // takes two and a copy. Where the mapping fails, through `scratch` and upload().
  template <class Fill>
  void write(std::size_t bytes, std::vector<std::uint8_t>& scratch, Fill&& fill) {
    if (bytes == 0) return;
    reserve(bytes);
    void* p = glMapNamedBufferRange(id, 0, static_cast<GLsizeiptr>(bytes), GL_MAP_WRITE_BIT | GL_MAP_INVALIDATE_BUFFER_BIT);
    if (p) {
      fill(p);
      if (glUnmapNamedBuffer(id) == GL_TRUE) return;  // else its store was lost while mapped: again
    }
    scratch.resize(bytes);
    fill(scratch.data());
    upload(scratch.data(), bytes);
  }
};

// draw_many: quads under this many pixels high keep no order across models (see there); part
// cards under a quarter of it (a body part of a character about that high: the flow test bed's
// part cards at 8 degrees keep 25.83 dB with 4 or 8 pixels, 25.73 dB with 16).
constexpr float kLayerMinPixels = 16.0f;
constexpr float kLayerMinCardPixels = 4.0f;

// The screen rectangle (pixels, x0, y0, x1, y1) that holds quad `b` as kBillboardVs places it
// (the planner's rectangle of the window, which holds the fitted one), for `camera`'s view and
// projection `viewproj`. A corner at or behind the eye gives the whole screen.
glm::vec4 quad_screen_rect(const BillboardGpu& b, const SceneCamera& camera, const glm::mat4& viewproj) {
  const glm::vec3 ta(b.ta_half);
  glm::vec3 ax, ay;
  if (b.axis_x.w > 0.5f) {
    ax = glm::vec3(b.axis_x);
    ay = glm::vec3(b.axis_y);
  } else {  // facing the eye: the snapshot camera's Ho and Uo (section 4.2), as the shader makes them
    const SnapshotCamera sc = make_snapshot_camera(ta, camera.eye, camera.up, b.ta_half.w);
    ax = b.ta_half.w * sc.ho;
    ay = b.ta_half.w * sc.uo;
  }
  const float w = static_cast<float>(camera.width), hgt = static_cast<float>(camera.height);
  glm::vec2 lo(1e30f), hi(-1e30f);
  for (int k = 0; k < 4; ++k) {
    const float cx = (k & 1) ? b.rect.z : b.rect.x, cy = (k & 2) ? b.rect.w : b.rect.y;
    const glm::vec4 c = viewproj * glm::vec4(ta + cx * ax + cy * ay, 1.0f);
    if (!(c.w > 1e-6f)) return glm::vec4(0.0f, 0.0f, w, hgt);
    const glm::vec2 px((c.x / c.w * 0.5f + 0.5f) * w, (c.y / c.w * 0.5f + 0.5f) * hgt);
    lo = glm::min(lo, px);
    hi = glm::max(hi, px);
  }
  return glm::vec4(lo, hi);
}

}  // namespace

// The atlas's GL objects: the pages' textures (colour, depth, and the relit normals and card
// offsets where the config asks for them), their framebuffer and the fitted rectangles, owned by
// every renderer that draws into it (ImpostorConfig::first_page: renderers of several models may
// share one, so that draw_many draws all their quads in one draw).
struct AtlasGl {
  GLuint atlas = 0, atlas_depth = 0, atlas_fbo = 0;
  GLuint atlas_normal = 0;  // relit snapshots' normals, same pages as the atlas
  GLuint atlas_offset = 0;  // depth-corrected cards' masked plane offsets (RG16F), same pages
  GLuint atlas_offset_wide = 0;  // the same at a quarter of the resolution, made by kCoverageCs
  GLuint coverage = 0;  // quads fitted to the coverage: a rectangle (vec4) per smallest-window slot
  bool layered = false, relight = false, parallax = false;
  int page_size = 0, pages = 0, smallest_window = 0;
  AtlasGl() = default;
  AtlasGl(const AtlasGl&) = delete;
  AtlasGl& operator=(const AtlasGl&) = delete;
  ~AtlasGl() {
    glDeleteTextures(1, &atlas);
    if (atlas_normal) glDeleteTextures(1, &atlas_normal);
    if (atlas_offset) glDeleteTextures(1, &atlas_offset);
    if (atlas_offset_wide) glDeleteTextures(1, &atlas_offset_wide);
    if (layered)
      glDeleteTextures(1, &atlas_depth);
    else
      glDeleteRenderbuffers(1, &atlas_depth);
    glDeleteFramebuffers(1, &atlas_fbo);
    glDeleteBuffers(1, &coverage);
  }
};

struct Renderer::Impl {
  const Model* model = nullptr;
  ImpostorConfig config;
  struct Lod {
    GLuint vbo = 0, ibo = 0, vao_geometry = 0, vao_snapshot = 0;
    GLuint part_ibo = 0, vao_part_snapshot = 0;  // body parts' triangles (Model::part_indices)
  };
  int parts = 1;  // body parts of the model (1: no part index buffers)
  std::vector<Lod> lods;
  std::vector<GLuint> textures;  // per model texture
  std::vector<GLuint> samplers;  // per material: its TextureSampler as a GL sampler object
  GLuint white = 0;
  GLuint palette_buffer = 0, palette_texture = 0;
  // kShadeFs's variants for the geometry and for the snapshots: [0] plain, [1] textured, [2] textured
  // and masked (alpha cutoff); [3, 6) the same with vertex colours (BB_COLORED); each with its
  // uniforms' locations.
  static constexpr std::size_t kShadeVariants = 6;
  struct ShadeProgram {
    std::array<GLuint, kShadeVariants> prog{};
    std::array<GLint, kShadeVariants> color{}, cutoff{}, lit{}, emissive{}, blend{}, viewproj{}, cut{}, first_cap{};
    static std::size_t variant(const Material& m) {
      return (m.alpha_mask || m.alpha_blend ? 2 : m.texture >= 0 ? 1 : 0) + (m.vertex_colors ? 3 : 0);
    }
  } shade_geometry, shade_snapshot;
  GLuint prog_clear = 0;
  // Multisampled snapshots (ImpostorConfig::snapshot_samples > 1): a scratch page, resolved.
  GLuint prog_resolve = 0, scratch_color = 0, scratch_depth = 0, scratch_fbo = 0;
  // Quads fitted to the coverage: the pass's program (its rectangles: AtlasGl::coverage).
  GLuint prog_coverage = 0;
  // Depth-corrected part cards (ImpostorConfig::parallax_cards, layered snapshots with one sample).
  bool parallax = false;
  bool depth_pass = false;  // ImpostorConfig::parallax_depth_pass
  bool relight = false;     // ImpostorConfig::relight (layered, one-sample snapshots only)
  bool fits_due = false;  // a snapshot of this frame wants its rectangle
  bool any_blended = false;  // the model has an alpha-blended material
  // DrawOptions::time_stages: timestamps at the start and after snapshots, coverage, geometry,
  // impostors.
  std::array<GLuint, 5> stamps{};
  bool stamped = false;
  void stamp(bool on, int k) {
    if (on) glQueryCounter(stamps[k], GL_TIMESTAMP);
  }
  int snapshot_samples = 1;
  // DrawOptions::flush_every_indices: whether the GL is a software rasterizer; for the current
  // draw(), whether its option is auto and the interval it asks for (0: no flushes); for the pass
  // being drawn, the interval (0: none) and the indices drawn since the last flush.
  bool software = false;
  int coverage_group = 4;  // invocations per side of the coverage pass's work groups
  bool flush_auto = true;
  std::size_t flush_every = 0, flush_at = 0, unflushed = 0;
  // Sets flush_at for a pass into the bound draw framebuffer; `indices()` gives the pass's
  // indices (only asked when flushes are on). Auto flushes only single-sampled passes of
  // `intervals` flush intervals and more: a short pass leaves no vertices to shade while the
  // rasterizer works, and every flush has a lasting cost on llvmpipe (a few flushes in the first
  // frame made the later impostor frames of the flow test bed 7 % slower, 1.59 -> 1.71 ms at 8
  // degrees: it seems to keep more scenes in rotation afterwards). The geometry pass flushes from
  // two intervals; a snapshot pass from six, since it ends in a framebuffer change, which flushes
  // anyway (our four bodies' worst case, 32,000 indices a model: no gain from flushing within).
  template <class Indices>
  void flushes_for_bound_target(Indices&& indices, std::size_t intervals) {
    flush_at = 0;
    unflushed = 0;
    if (flush_every == 0) return;
    if (!flush_auto) {
      flush_at = flush_every;
      return;
    }
    GLint sample_buffers = 0;
    glGetIntegerv(GL_SAMPLE_BUFFERS, &sample_buffers);
    if (sample_buffers == 0 && indices() >= intervals * flush_every) flush_at = flush_every;
  }
  // Indices of one instance of level `lod`, or of its body part `part` (>= 0).
  std::size_t instance_indices(int lod, int part) const {
    const MeshLod& ml = model->lods[lod];
    std::size_t n = 0;
    if (part < 0) {
      for (const Primitive& p : ml.primitives) n += p.index_count;
    } else {
      const PartIndices& pi = model->part_indices(lod);
      for (std::size_t k = 0; k < ml.primitives.size(); ++k) {
        const PartIndices::Range& r = pi.ranges[k * parts + part];
        n += r.count + r.caps;
      }
    }
    return n;
  }
  // Indices of the snapshots due[first, first + count).
  std::size_t due_indices(std::size_t first, std::size_t count) const {
    std::size_t n = 0;
    for (std::size_t i = first; i < first + count; ++i) n += instance_indices(scratch_lod[i], scratch_part[i]);
    return n;
  }
  void drew_indices(std::size_t n) {
    unflushed += n;
    if (flush_at > 0 && unflushed >= flush_at) {
      glFlush();
      unflushed = 0;
    }
  }
  // The atlas's objects, which renderers sharing the atlas hold alike.
  std::shared_ptr<AtlasGl> shared_atlas;
  bool layered = false;  // one snapshot pass for all pages (depth is then a texture array too)
  std::vector<std::array<GLuint, 2>> lod_runs;  // per LOD: (count, first) in snapshot_scratch
  GLuint vao_billboard = 0;
  // Pulled quads (ImpostorConfig::quad_fetch): one indexed draw, the vertex shader fetching quad
  // gl_VertexID / 4 from a buffer texture over `billboards`, instead of an instance per quad.
  bool pull_quads = false;
  std::size_t max_pulled_quads = 0;     // GL_MAX_TEXTURE_BUFFER_SIZE / 7
  GLuint quad_texture = 0;              // GL_TEXTURE_BUFFER, RGBA32F, over `billboards`
  std::size_t quad_texture_bytes = 0;   // `billboards`' capacity when quad_texture was attached to it
  GLuint quad_indices = 0;              // 0 1 2 2 1 3, then the same + 4 per quad (vao_billboard's)
  std::size_t quad_index_capacity = 0;  // quads the index buffer holds
  StreamBuffer instances, snapshots, billboards;
  std::vector<InstanceGpu> instance_scratch;
  std::vector<SnapshotGpu> snapshot_scratch;
  // Blending: the quads' -depth, and their order back to front.
  std::vector<float> billboard_depth;
  std::vector<std::uint32_t> billboard_order;
  // The geometry pass's blended surfaces, back to front: each instance's level, in the plan's
  // order, and the order they are drawn in.
  std::vector<int> instance_lod;
  std::vector<float> blend_depth;
  std::vector<std::uint32_t> blend_order;
  DepthOrder depth_order;
  std::vector<BillboardGpu> billboard_scratch;
  std::vector<std::uint8_t> write_scratch;  // StreamBuffer::write's where a mapping fails
  // draw_many: every renderer's quads of the frame on screen, their order back to front and
  // layers (in the first renderer's), and per layer this renderer's range of its upload.
  std::vector<LayerQuad> many_quads;
  std::vector<float> many_depth;
  std::vector<std::uint32_t> many_order, many_index;
  // One atlas's draw: each quad's model, and each model's first quad (n + 1: the total last).
  std::vector<std::uint32_t> many_model, many_first;
  std::vector<int> many_layer;
  ImpostorLayers layering;
  std::vector<std::array<GLuint, 2>> layer_ranges;  // (first, count)
  std::vector<GLuint> layer_next;                   // draw_many: where each layer's next quad goes
  struct Due {
    std::int32_t lod, page, index;  // index into the plan's list of that lod
    std::int32_t part;              // body part, -1: the whole character
  };
  std::vector<Due> due;
  std::vector<int> scratch_lod, scratch_part;  // per snapshot_scratch entry
  glm::vec3 light = glm::normalize(glm::vec3(0.4f, 0.8f, 0.6f));
  // The planner's cache (FramePlan::cache_id) whose snapshots this renderer's windows hold: that of
  // the last plan it took snapshots of (0: none yet).
  std::uint64_t cache_id = 0;

  struct BillboardProgram {
    GLuint prog = 0;
    GLint viewproj = -1, eye = -1, up = -1, samples = -1, sample_pos = -1, depth_pass = -1;
  };
  // The impostor shader per edge mode (BB_EDGES of kBillboardFs; 3: the per-sample program).
  std::array<BillboardProgram, 5> bb;
  int sample_count = 0;  // of the sample positions last given to the impostor shader
  std::string billboard_source;  // the impostor programs' sources but for BB_EDGES (draw_many shares alike ones)

  // The impostor pass (draw()'s stage 3, and draw_many()'s): the program for the edge mode the
  // bound framebuffer gives DrawOptions::edges, and the quads' state.
  struct ImpostorPass {
    int mode = 1;        // BB_EDGES of kBillboardFs, or 3: the per-sample program
    int samples = 1;     // the bound framebuffer's samples
    bool cards = false;  // the plan's quads are part cards
  };
  std::vector<ImpostorPass> many_pass;  // draw_many: each renderer's pass (in the first renderer's)
  static ImpostorPass impostor_pass(ImpostorEdges edges, bool cards) {
    ImpostorPass p;
    p.cards = cards;
    GLint sample_buffers = 0, samples = 1;
    glGetIntegerv(GL_SAMPLE_BUFFERS, &sample_buffers);
    if (sample_buffers > 0) glGetIntegerv(GL_SAMPLES, &samples);
    p.samples = std::clamp(static_cast<int>(samples), 1, 16);
    switch (edges) {
      case ImpostorEdges::kSamples: p.mode = sample_buffers > 0 ? 3 : 0; break;
      case ImpostorEdges::kAlphaToCoverage: p.mode = sample_buffers > 0 ? 2 : 0; break;
      case ImpostorEdges::kAlphaTest: p.mode = 0; break;
      case ImpostorEdges::kBlend: p.mode = 1; break;
      case ImpostorEdges::kCentre: p.mode = 4; break;
    }
    return p;
  }

  // billboard_order: the plan's quads back to front (by -depth of Ta along the view direction,
  // billboard_depth).
  void order_back_to_front(const FramePlan& plan) {
    const glm::vec3 fwd = glm::normalize(plan.camera.target - plan.camera.eye);
    billboard_depth.resize(plan.billboards.size());
    for (std::size_t i = 0; i < plan.billboards.size(); ++i)
      billboard_depth[i] = -glm::dot(glm::vec3(plan.billboards[i].ta_half) - plan.camera.eye, fwd);
    depth_order.sort(billboard_depth, billboard_order);
  }

  // Uploads `n` quads in the order they are drawn and gives the pass's program this frame's
  // uniforms.
  void upload_impostors(const ImpostorPass& p, const FramePlan& plan, const BillboardGpu* quads, std::size_t n,
                        const glm::mat4& viewproj) {
    billboards.upload(quads, n * sizeof(BillboardGpu));
    impostor_uniforms(p, plan, n, viewproj);
  }
  // The same, the quads written by gather(BillboardGpu* out) into the buffer in drawing order.
  template <class Gather>
  void write_impostors(const ImpostorPass& p, const FramePlan& plan, std::size_t n, const glm::mat4& viewproj,
                       Gather&& gather) {
    billboards.write(n * sizeof(BillboardGpu), write_scratch, [&](void* out) { gather(static_cast<BillboardGpu*>(out)); });
    impostor_uniforms(p, plan, n, viewproj);
  }
  void impostor_uniforms(const ImpostorPass& p, const FramePlan& plan, std::size_t n, const glm::mat4& viewproj) {
    if (pull_quads) fit_pulled_quads(n);
    const BillboardProgram& bp = bb[static_cast<std::size_t>(p.mode)];
    glProgramUniformMatrix4fv(bp.prog, bp.viewproj, 1, GL_FALSE, glm::value_ptr(viewproj));
    glProgramUniform3fv(bp.prog, bp.eye, 1, glm::value_ptr(plan.camera.eye));
    glProgramUniform3fv(bp.prog, bp.up, 1, glm::value_ptr(plan.camera.up));
    if (p.mode == 3 && p.samples != sample_count) {
      // Where this framebuffer's samples lie in the pixel (GL: [0, 1]^2 from its lower left).
      sample_count = p.samples;
      std::array<float, 32> pos{};
      for (int k = 0; k < p.samples; ++k) {
        glGetMultisamplefv(GL_SAMPLE_POSITION, static_cast<GLuint>(k), &pos[2 * k]);
        pos[2 * k] -= 0.5f;
        pos[2 * k + 1] -= 0.5f;
      }
      glProgramUniform2fv(bp.prog, bp.sample_pos, p.samples, pos.data());
      glProgramUniform1i(bp.prog, bp.samples, p.samples);
    }
  }

  // This renderer's impostor program, atlas textures, fitted rectangles and uploaded quads.
  void bind_impostors(const ImpostorPass& p, bool use_program = true) {
    if (use_program) glUseProgram(bb[static_cast<std::size_t>(p.mode)].prog);
    glBindTextureUnit(2, shared_atlas->atlas);
    if (parallax) {
      glBindTextureUnit(4, shared_atlas->atlas_offset);
      glBindTextureUnit(6, shared_atlas->atlas_offset_wide);
    }
    if (relight) glBindTextureUnit(5, shared_atlas->atlas_normal);
    glBindVertexArray(vao_billboard);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, shared_atlas->coverage);
    if (pull_quads) glBindTextureUnit(7, quad_texture);
  }

  // The pass's blending and sampling state, the same whichever renderer draws; returns whether
  // multisampling was turned off (end_impostor_state turns it on again).
  static bool begin_impostor_state(int mode) {
    if (mode == 2) {
      // The samples covered are wholly covered: alpha 1 in them (else the resolved pixel would
      // carry the coverage twice, alpha below the premultiplied colour: a bright fringe).
      glEnable(GL_SAMPLE_ALPHA_TO_COVERAGE);
      glEnable(GL_SAMPLE_ALPHA_TO_ONE);
    }
    // Blended quads are rasterized single-sampled (each pixel whole, from its centre): the four
    // taps already give the edge its coverage, so the samples add only cost. Flow test bed, 4x
    // MSAA, llvmpipe: the same frames as per-sample rasterization, part cards 10-20 % faster,
    // whole impostors 3-6 % (and then faster than alpha to coverage).
    const bool single_sampled = mode == 1 && glIsEnabled(GL_MULTISAMPLE) == GL_TRUE;
    if (single_sampled) glDisable(GL_MULTISAMPLE);
    if (mode == 1) {
      glEnable(GL_BLEND);
      glBlendFunc(GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
    }
    return single_sampled;
  }
  static void end_impostor_state(bool single_sampled) {
    if (single_sampled) glEnable(GL_MULTISAMPLE);
    glDisable(GL_BLEND);
    glDisable(GL_SAMPLE_ALPHA_TO_COVERAGE);
    glDisable(GL_SAMPLE_ALPHA_TO_ONE);
  }

  // draw_many's quads: the depth test as draw() leaves it, no culling, the whole scene's viewport.
  static void begin_many_impostors(const SceneCamera& camera) {
    glEnable(GL_DEPTH_TEST);
    glDepthMask(GL_TRUE);
    glDepthFunc(GL_LESS);
    glDisable(GL_CULL_FACE);
    glViewport(0, 0, camera.width, camera.height);
  }
  // The end of draw() and draw_many(): no VAO or program bound, and no sampler object (a material's
  // must not outlive the draw).
  static void end_draw() {
    glBindVertexArray(0);
    glUseProgram(0);
    glBindSampler(1, 0);
  }

  // Pulled quads: the buffer texture over `billboards` (attached again where its store grew) and
  // vao_billboard's index buffer, for `n` uploaded quads. Only when they grow, not every frame.
  void fit_pulled_quads(std::size_t n) {
    assert(n <= max_pulled_quads && "more quads than a buffer texture holds");
    if (quad_texture == 0) glCreateTextures(GL_TEXTURE_BUFFER, 1, &quad_texture);
    if (quad_texture_bytes != billboards.capacity) {
      glTextureBuffer(quad_texture, GL_RGBA32F, billboards.id);
      quad_texture_bytes = billboards.capacity;
    }
    if (n <= quad_index_capacity) return;
    quad_index_capacity = std::max(n, 2 * quad_index_capacity);
    std::vector<GLuint> idx(6 * quad_index_capacity);
    for (std::size_t q = 0; q < quad_index_capacity; ++q) {
      const GLuint v = static_cast<GLuint>(4 * q);
      const GLuint t[6] = {v, v + 1, v + 2, v + 2, v + 1, v + 3};
      std::copy(t, t + 6, idx.begin() + static_cast<std::ptrdiff_t>(6 * q));
    }
    glNamedBufferData(quad_indices, static_cast<GLsizeiptr>(idx.size() * 4), idx.data(), GL_STATIC_DRAW);
  }

  // One draw of uploaded quads [first, first + count) as this renderer fetches them (with the vertex
  // array bind_impostors bound, whose quads they are: draw_many may draw them with another renderer's
  // alike program): an instanced strip of 4 vertices each, or 6 indices each with the quad pulled by
  // the vertex shader.
  void draw_quads(GLuint first, GLsizei count) {
    if (!pull_quads) {
      glDrawArraysInstancedBaseInstance(GL_TRIANGLE_STRIP, 0, 4, count, first);
      return;
    }
    glDrawElements(GL_TRIANGLES, 6 * count, GL_UNSIGNED_INT,
                   reinterpret_cast<const void*>(static_cast<std::uintptr_t>(first) * 6 * 4));
  }

  // Draws uploaded quads [first, first + count) (bound by bind_impostors).
  void draw_impostor_range(const ImpostorPass& p, GLuint first, GLsizei count) {
    if (count <= 0) return;
    // Blended part cards are sorted back to front by their centres like whole impostors and write
    // no depth, so a card's soft edge never hides the card behind it. (Drawing their opaque texels
    // first with depth, then everything blended, cost a second pass over every card for no
    // measured gain: flow test bed, 8 degrees, 24.99 against 25.03 dB, 3.3x against 1.8x.)
    const BillboardProgram& bp = bb[static_cast<std::size_t>(p.mode)];
    if (p.mode == 1 && p.cards && depth_pass) {
      // Depth-corrected blended cards: first the opaque texels' surface depth, so overlapping
      // cards (at the joints) hide each other per pixel; then the colours, blended, where they
      // are not behind it.
      glProgramUniform1i(bp.prog, bp.depth_pass, 1);
      glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
      draw_quads(first, count);
      glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
      glProgramUniform1i(bp.prog, bp.depth_pass, 0);
      glDepthFunc(GL_LEQUAL);
    }
    if (p.mode == 1 && p.cards) glDepthMask(GL_FALSE);
    draw_quads(first, count);
    glDepthFunc(GL_LESS);
    glDepthMask(GL_TRUE);
  }

  // `light` into every program that shades (the impostor programs only when they relight: elsewhere
  // the location is -1 and the call does nothing).
  void upload_light() {
    auto upload = [&](GLuint p) { glProgramUniform3fv(p, glGetUniformLocation(p, "u_light"), 1, glm::value_ptr(light)); };
    for (const ShadeProgram* sp : {&shade_geometry, &shade_snapshot})
      for (GLuint p : sp->prog)
        if (p) upload(p);  // 0: a vertex-colour variant the model does not use
    for (const BillboardProgram& b : bb) upload(b.prog);
  }

  // Back-face culling as the material asks (Material::double_sided), GL_CULL_FACE changed only when
  // it must (`culling` mirrors it within a draw: off at draw()'s start and for every pass that is not
  // a material's: the windows' clears, the resolve, the quads).
  bool culling = false;
  bool cut_open = false;  // drawing a body part's snapshot (draw_part)
  void set_culling(bool on) {
    if (on == culling) return;
    if (on)
      glEnable(GL_CULL_FACE);
    else
      glDisable(GL_CULL_FACE);
    culling = on;
  }

  // Uses the material's variant of `sp` and gives it the material.
  void set_material(const ShadeProgram& sp, int material) {
    const Material& m = model->materials[material];
    const std::size_t v = ShadeProgram::variant(m);
    glUseProgram(sp.prog[v]);
    glProgramUniform4fv(sp.prog[v], sp.color[v], 1, glm::value_ptr(m.base_color));
    glProgramUniform1f(sp.prog[v], sp.cutoff[v], m.alpha_blend ? 0.0f : m.alpha_cutoff);
    glProgramUniform1f(sp.prog[v], sp.blend[v], m.alpha_blend ? 1.0f : 0.0f);
    glProgramUniform1f(sp.prog[v], sp.lit[v], m.unlit ? 0.0f : 1.0f);
    glProgramUniform3fv(sp.prog[v], sp.emissive[v], 1, glm::value_ptr(m.emissive));
    if (sp.cut[v] >= 0) glProgramUniform1f(sp.prog[v], sp.cut[v], cut_open ? 1.0f : 0.0f);
    if (v % 3 > 0) {
      glBindTextureUnit(1, m.texture >= 0 ? textures[m.texture] : white);
      glBindSampler(1, samplers[material]);
    }
  }

  // Clears the rects of snapshot_scratch[first, first + count) and draws those snapshots into
  // the bound framebuffer (the entries are sorted by LOD; scratch_lod holds each one's level).
  // Clip distances must be on.
  void draw_snapshot_range(std::size_t first, std::size_t count) {
    set_culling(false);
    glUseProgram(prog_clear);
    glBindVertexArray(lods[0].vao_snapshot);
    glDepthFunc(GL_ALWAYS);
    glDrawArraysInstancedBaseInstance(GL_TRIANGLE_STRIP, 0, 4, static_cast<GLsizei>(count), static_cast<GLuint>(first));
    glDepthFunc(GL_LESS);
    for (std::size_t b = first, end = first + count; b < end;) {
      std::size_t e = b;
      while (e < end && scratch_lod[e] == scratch_lod[b] && scratch_part[e] == scratch_part[b]) ++e;
      first_cap_of(scratch_part[b] < 0 ? -1 : scratch_lod[b]);
      if (scratch_part[b] < 0) {
        glBindVertexArray(lods[scratch_lod[b]].vao_snapshot);
        draw_lod(shade_snapshot, scratch_lod[b], static_cast<GLsizei>(e - b), static_cast<GLuint>(b));
      } else {
        glBindVertexArray(lods[scratch_lod[b]].vao_part_snapshot);
        draw_part(scratch_lod[b], scratch_part[b], static_cast<GLsizei>(e - b), static_cast<GLuint>(b));
      }
      b = e;
    }
  }

  // Which primitives a draw takes: the opaque (and alpha-tested) ones, the alpha-blended ones, or
  // both in that order (a snapshot's window holds one character, so its blended surfaces need only
  // follow its own opaque ones; the geometry pass draws every character's opaque surfaces first).
  enum class Surfaces { kOpaque, kBlended, kBoth };
  bool blended(const Primitive& p) const { return model->materials[p.material].alpha_blend; }
  // Blending for alpha-blended primitives: premultiplied over what is drawn, tested against the
  // depth but not writing it; depth-corrected cards' plane offsets stay those of the opaque surface.
  void blend_state(bool on) {
    if (on) {
      glEnable(GL_BLEND);
      glBlendFunc(GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
      glDepthMask(GL_FALSE);
      if (parallax) glColorMaski(2, GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
    } else {
      glDisable(GL_BLEND);
      glDepthMask(GL_TRUE);
      if (parallax) glColorMaski(2, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    }
  }

  // `draw()` with `material` in `sp`, blended if the material is (blend_state around it).
  template <class Draw>
  void with_material(const ShadeProgram& sp, int material, Draw&& draw) {
    set_material(sp, material);
    set_culling(!model->materials[material].double_sided);
    const bool blend = model->materials[material].alpha_blend;
    if (blend) blend_state(true);
    draw();
    if (blend) blend_state(false);
  }

  // Calls draw(k) for each primitive k of `ml` that `surfaces` takes and `keep(k)` allows, the
  // opaque ones first, with its material in `sp` (blended where it blends).
  template <class Keep, class Draw>
  void each_primitive(const ShadeProgram& sp, const MeshLod& ml, Surfaces surfaces, Keep&& keep, Draw&& draw) {
    for (bool blend : {false, true}) {
      if (blend ? surfaces == Surfaces::kOpaque || !any_blended : surfaces == Surfaces::kBlended) continue;
      for (std::size_t k = 0; k < ml.primitives.size(); ++k)
        if (blended(ml.primitives[k]) == blend && keep(k)) with_material(sp, ml.primitives[k].material, [&] { draw(k); });
    }
  }

  // The triangles of body part `part` only (the part index buffer's ranges).
  void draw_part(int lod, int part, GLsizei count, GLuint base_instance) {
    // A part's triangles end where the next part's begin; its caps close those cuts
    // (PartIndices::Range::caps), drawn with it, culled as its material says. Culled without caps,
    // the cuts showed the background; drawn with both faces instead, the part's inside, lit as
    // kShadeFs's u_cut says (flow test bed, part cards at 8 degrees: 3.06x the geometry's speed at
    // 24.52 dB without caps, 2.62x at 25.84 dB with both faces, 2.95x at 26.20 dB with caps).
    cut_open = true;  // set_material's u_cut on: a double-sided material's back faces seen through a cut
    const MeshLod& ml = model->lods[lod];
    const PartIndices& pi = model->part_indices(lod);
    auto range = [&](std::size_t k) -> const PartIndices::Range& { return pi.ranges[k * parts + part]; };
    each_primitive(shade_snapshot, ml, Surfaces::kBoth, [&](std::size_t k) { return range(k).count > 0; }, [&](std::size_t k) {
      const PartIndices::Range& r = range(k);
      const std::uint32_t n = r.count + r.caps;
      glDrawElementsInstancedBaseInstance(GL_TRIANGLES, static_cast<GLsizei>(n), GL_UNSIGNED_INT,
                                          reinterpret_cast<const void*>(static_cast<std::uintptr_t>(r.first) * 4), count,
                                          base_instance);
      drew_indices(static_cast<std::size_t>(n) * static_cast<std::size_t>(count));
    });
    cut_open = false;
  }

  // The snapshot shader's u_first_cap for level `lod`'s part snapshots (its vertex count: the caps'
  // vertices follow), or for whole snapshots (-1: none), set where it changes.
  int first_cap_lod = -1;
  void first_cap_of(int lod) {
    if (lod == first_cap_lod) return;
    const GLint first = lod < 0 ? 0x7fffffff : static_cast<GLint>(model->lods[lod].vertices.size());
    for (std::size_t v = 0; v < kShadeVariants; ++v)
      if (shade_snapshot.prog[v] && shade_snapshot.first_cap[v] >= 0) glProgramUniform1i(shade_snapshot.prog[v], shade_snapshot.first_cap[v], first);
    first_cap_lod = lod;
  }

  void take_snapshots(const FramePlan& plan, bool time_stages);
  void take_snapshot_passes(const FramePlan& plan);  // the draws; sets fits_due

  // The game's GL state that would change what the snapshot passes draw into the atlas: saved and
  // set for the passes by begin(), put back as found by end(). Its scissor rectangle and polygon
  // offset are of its own framebuffer (a UI's rectangle, a decal's offset): a snapshot cut or
  // shifted by them would be drawn from the atlas until its cache test fires. They still apply to
  // the scene's passes (geometry and quads), which draw into the game's framebuffer.
  struct AtlasPassState {
    GLint fbo = 0, viewport[4] = {0, 0, 0, 0}, polygon_mode[2] = {GL_FILL, GL_FILL};
    GLboolean scissor = GL_FALSE, offset_fill = GL_FALSE, discard = GL_FALSE;
    GLboolean clip[4] = {GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE};
    GLboolean mask[3][4] = {};  // colour write masks of the atlas's draw buffers 0-2
    // Multisampled snapshots: drawn with every sample, nothing masked.
    bool samples = false;
    GLboolean multisample = GL_TRUE, alpha_to_coverage = GL_FALSE, sample_coverage = GL_FALSE, sample_mask = GL_FALSE;
    void begin(bool multisampled) {
      glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &fbo);
      glGetIntegerv(GL_VIEWPORT, viewport);
      glGetIntegerv(GL_POLYGON_MODE, polygon_mode);
      scissor = glIsEnabled(GL_SCISSOR_TEST);
      offset_fill = glIsEnabled(GL_POLYGON_OFFSET_FILL);
      discard = glIsEnabled(GL_RASTERIZER_DISCARD);
      for (int k = 0; k < 4; ++k) clip[k] = glIsEnabled(GL_CLIP_DISTANCE0 + k);
      for (GLuint b = 0; b < 3; ++b) glGetBooleani_v(GL_COLOR_WRITEMASK, b, mask[b]);
      if (scissor) glDisable(GL_SCISSOR_TEST);
      if (offset_fill) glDisable(GL_POLYGON_OFFSET_FILL);
      if (discard) glDisable(GL_RASTERIZER_DISCARD);
      if (polygon_mode[0] != GL_FILL) glPolygonMode(GL_FRONT_AND_BACK, GL_FILL);
      for (int k = 0; k < 4; ++k) glEnable(GL_CLIP_DISTANCE0 + k);  // the snapshot shaders' window edges
      glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
      samples = multisampled;
      if (samples) {
        multisample = glIsEnabled(GL_MULTISAMPLE);
        alpha_to_coverage = glIsEnabled(GL_SAMPLE_ALPHA_TO_COVERAGE);
        sample_coverage = glIsEnabled(GL_SAMPLE_COVERAGE);
        sample_mask = glIsEnabled(GL_SAMPLE_MASK);
        if (!multisample) glEnable(GL_MULTISAMPLE);
        if (alpha_to_coverage) glDisable(GL_SAMPLE_ALPHA_TO_COVERAGE);
        if (sample_coverage) glDisable(GL_SAMPLE_COVERAGE);
        if (sample_mask) glDisable(GL_SAMPLE_MASK);
      }
    }
    void end() const {
      for (int k = 0; k < 4; ++k)
        if (!clip[k]) glDisable(GL_CLIP_DISTANCE0 + k);
      for (GLuint b = 0; b < 3; ++b) glColorMaski(b, mask[b][0], mask[b][1], mask[b][2], mask[b][3]);
      if (polygon_mode[0] != GL_FILL) glPolygonMode(GL_FRONT_AND_BACK, static_cast<GLenum>(polygon_mode[0]));
      if (discard) glEnable(GL_RASTERIZER_DISCARD);
      if (offset_fill) glEnable(GL_POLYGON_OFFSET_FILL);
      if (scissor) glEnable(GL_SCISSOR_TEST);
      if (samples) {
        if (!multisample) glDisable(GL_MULTISAMPLE);
        if (alpha_to_coverage) glEnable(GL_SAMPLE_ALPHA_TO_COVERAGE);
        if (sample_coverage) glEnable(GL_SAMPLE_COVERAGE);
        if (sample_mask) glEnable(GL_SAMPLE_MASK);
      }
      glBindFramebuffer(GL_DRAW_FRAMEBUFFER, static_cast<GLuint>(fbo));
      glViewport(viewport[0], viewport[1], viewport[2], viewport[3]);
    }
  };

  // Instances [base_instance, base_instance + count) of level `lod`, its `surfaces`, in as many
  // draws as the flushes (flush_at) want.
  void draw_lod(const ShadeProgram& sp, int lod, GLsizei count, GLuint base_instance, Surfaces surfaces = Surfaces::kBoth) {
    const MeshLod& ml = model->lods[lod];
    const std::size_t per = instance_indices(lod, -1);
    if (surfaces == Surfaces::kBlended && !any_blended) return;
    for (GLsizei done = 0; done < count;) {
      GLsizei n = count - done;
      if (flush_at > 0 && per > 0) {
        const std::size_t left = flush_at > unflushed ? flush_at - unflushed : 1;
        n = std::min<GLsizei>(n, static_cast<GLsizei>(std::max<std::size_t>(1, (left + per - 1) / per)));
      }
      std::size_t drawn = 0;  // indices of one instance
      each_primitive(sp, ml, surfaces, [](std::size_t) { return true; }, [&](std::size_t k) {
        const Primitive& p = ml.primitives[k];
        glDrawElementsInstancedBaseInstance(GL_TRIANGLES, static_cast<GLsizei>(p.index_count), GL_UNSIGNED_INT,
                                            reinterpret_cast<const void*>(static_cast<std::uintptr_t>(p.first_index) * 4), n,
                                            base_instance + static_cast<GLuint>(done));
        drawn += p.index_count;
      });
      drew_indices(drawn * static_cast<std::size_t>(n));
      done += n;
    }
  }
};

void Renderer::Impl::take_snapshots(const FramePlan& plan, bool time_stages) {
  take_snapshot_passes(plan);
  stamp(time_stages, 1);
  if (fits_due || (parallax && !snapshot_scratch.empty())) {
    // The new snapshots' covered rectangles (one work group each; those not fitted return at once)
    // and, for depth-corrected cards, their wide plane offsets.
    glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT | GL_FRAMEBUFFER_BARRIER_BIT);
    glUseProgram(prog_coverage);
    glBindTextureUnit(2, shared_atlas->atlas);
    if (parallax) {
      glBindTextureUnit(4, shared_atlas->atlas_offset);
      glBindImageTexture(0, shared_atlas->atlas_offset_wide, 0, GL_TRUE, 0, GL_WRITE_ONLY, GL_RG16F);
    }
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, shared_atlas->coverage);
    glBindBufferRange(GL_SHADER_STORAGE_BUFFER, 1, snapshots.id, 0,
                      static_cast<GLsizeiptr>(snapshot_scratch.size() * sizeof(SnapshotGpu)));
    glDispatchCompute(static_cast<GLuint>(snapshot_scratch.size()), 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_TEXTURE_FETCH_BARRIER_BIT);
  }
  stamp(time_stages, 2);
}

void Renderer::Impl::take_snapshot_passes(const FramePlan& plan) {
  fits_due = false;
  snapshot_scratch.clear();  // none this frame: no coverage step either (it reran over the last ones)
  const int nlods = static_cast<int>(lods.size());
  due.clear();
  for (int lod = 0; lod < static_cast<int>(plan.snapshots.size()); ++lod)
    for (std::size_t i = 0; i < plan.snapshots[lod].size(); ++i) {
      const int page = static_cast<int>(plan.snapshots[lod][i].window.w);
      assert(page >= config.first_page && page < config.first_page + config.max_pages && "plan from a planner with another ImpostorConfig");
      const int part = static_cast<int>(plan.snapshots[lod][i].part.x);
      due.push_back(Due{std::min(lod, nlods - 1), page, static_cast<std::int32_t>(i), part < parts ? part : -1});
    }
  if (due.empty()) return;
  // One pass for all pages when the vertex shader can choose the layer, else one per page; in a
  // pass, one draw per level, part and primitive.
  if (!layered || snapshot_samples > 1)
    std::sort(due.begin(), due.end(), [](const Due& a, const Due& b) {
      return a.page != b.page ? a.page < b.page : a.lod != b.lod ? a.lod < b.lod : a.part < b.part;
    });
  else
    std::sort(due.begin(), due.end(), [](const Due& a, const Due& b) { return a.lod != b.lod ? a.lod < b.lod : a.part < b.part; });
  scratch_lod.clear();
  scratch_part.clear();
  for (const Due& u : due) {
    snapshot_scratch.push_back(plan.snapshots[u.lod][u.index]);
    fits_due |= snapshot_scratch.back().part.z > 0.5f;
    scratch_lod.push_back(u.lod);
    scratch_part.push_back(u.part);
  }
  snapshots.upload(snapshot_scratch.data(), snapshot_scratch.size() * sizeof(SnapshotGpu));
  AtlasPassState game;
  game.begin(snapshot_samples > 1);
  glBindFramebuffer(GL_DRAW_FRAMEBUFFER, shared_atlas->atlas_fbo);
  glViewport(0, 0, config.page_size, config.page_size);
  if (snapshot_samples > 1) {
    // Page by page: drawn multisampled into the scratch page, then resolved into the atlas.
    for (std::size_t b = 0; b < due.size();) {
      std::size_t e = b;
      while (e < due.size() && due[e].page == due[b].page) ++e;
      glBindFramebuffer(GL_DRAW_FRAMEBUFFER, scratch_fbo);
      flushes_for_bound_target([&] { return due_indices(b, e - b); }, 6);
      draw_snapshot_range(b, e - b);
      // The resolve pass reuses the clear's vertex shader, whose clip distances keep every vertex.
      glBindFramebuffer(GL_DRAW_FRAMEBUFFER, shared_atlas->atlas_fbo);
      if (!layered) glNamedFramebufferTextureLayer(shared_atlas->atlas_fbo, GL_COLOR_ATTACHMENT0, shared_atlas->atlas, 0, due[b].page);
      glDisable(GL_DEPTH_TEST);
      set_culling(false);
      glUseProgram(prog_resolve);
      glBindTextureUnit(3, scratch_color);
      glBindVertexArray(lods[0].vao_snapshot);
      glDrawArraysInstancedBaseInstance(GL_TRIANGLE_STRIP, 0, 4, static_cast<GLsizei>(e - b), static_cast<GLuint>(b));
      glEnable(GL_DEPTH_TEST);
      b = e;
    }
  } else if (layered) {
    flushes_for_bound_target([&] { return due_indices(0, due.size()); }, 6);
    draw_snapshot_range(0, due.size());
  } else {
    flushes_for_bound_target([&] { return due_indices(0, due.size()); }, 6);
    for (std::size_t b = 0; b < due.size();) {
      std::size_t e = b;
      while (e < due.size() && due[e].page == due[b].page) ++e;
      glNamedFramebufferTextureLayer(shared_atlas->atlas_fbo, GL_COLOR_ATTACHMENT0, shared_atlas->atlas, 0, due[b].page);
      draw_snapshot_range(b, e - b);
      b = e;
    }
  }
  game.end();
}

Renderer::Renderer() : impl_(std::make_unique<Impl>()) {}

const Model& Renderer::model() const { return *impl_->model; }

bool Renderer::holds_snapshots_for(const FramePlan& plan) const {
  return plan.cache_plans_before == 0 || plan.cache_id == impl_->cache_id;
}

Result<std::unique_ptr<Renderer>> Renderer::create(const Model& model, const ImpostorConfig& config,
                                                    const Renderer* share_atlas) {
  if (Status valid = validate_impostor_config(config); !valid) return valid.error();
  std::unique_ptr<Renderer> r(new Renderer());
  Impl& d = *r->impl_;
  d.model = &model;
  d.config = config;
  d.any_blended = std::any_of(model.materials.begin(), model.materials.end(), [](const Material& m) { return m.alpha_blend; });
  while (glGetError() != GL_NO_ERROR) {
  }
  // kShadeFs's variants (Impl::ShadeProgram) of one program; those with vertex colours only where the model
  // has a material that uses them.
  const bool colored = std::any_of(model.materials.begin(), model.materials.end(), [](const Material& m) { return m.vertex_colors; });
  auto shade_program = [&model, colored](Impl::ShadeProgram& sp, const std::string& vs, const std::string& fs, const char* what) -> Status {
    const std::string variants[3] = {fs, with_define(fs, "BB_TEXTURED"), with_define(with_define(fs, "BB_TEXTURED"), "BB_MASKED")};
    for (std::size_t v = 0; v < (colored ? Impl::kShadeVariants : 3); ++v) {
      auto p = v < 3 ? program(vs, variants[v], what) : program(with_define(vs, "BB_COLORED"), with_define(variants[v - 3], "BB_COLORED"), what);
      if (!p) return p.error();
      sp.prog[v] = *p;
      sp.color[v] = glGetUniformLocation(*p, "u_color");
      sp.cutoff[v] = glGetUniformLocation(*p, "u_cutoff");
      sp.lit[v] = glGetUniformLocation(*p, "u_lit");
      sp.emissive[v] = glGetUniformLocation(*p, "u_emissive");
      sp.blend[v] = glGetUniformLocation(*p, "u_blend");
      sp.viewproj[v] = glGetUniformLocation(*p, "u_viewproj");
      sp.cut[v] = glGetUniformLocation(*p, "u_cut");
      sp.first_cap[v] = glGetUniformLocation(*p, "u_first_cap");
      glProgramUniform1i(*p, glGetUniformLocation(*p, "u_palette_size"), static_cast<GLint>(model.palette.size()));
    }
    return Ok{};
  };
  if (Status st = shade_program(d.shade_geometry, std::string(kCommon) + kGeometryVs, kShadeFs, "geometry shader"); !st)
    return st.error();
  d.layered = has_gl_extension("GL_ARB_shader_viewport_layer_array") && !std::getenv("BB_NO_LAYERED_SNAPSHOTS");
  d.software = software_rasterizer();
  d.snapshot_samples = std::clamp(config.snapshot_samples, 1, 16);
  // Relit snapshots and depth-corrected cards write more targets beside the atlas: layered
  // snapshots with one sample per texel only.
  const bool extra_targets = d.layered && d.snapshot_samples == 1;
  d.relight = config.relight && extra_targets;
  d.parallax = config.parallax_cards && extra_targets;
  std::string svs = d.layered ? layered(std::string(kCommon) + kSnapshotVs) : std::string(kCommon) + kSnapshotVs;
  std::string sfs = with_define(kShadeFs, "BB_SNAPSHOT");
  if (d.relight)  // snapshots of albedo and normals
    for (std::string* src : {&svs, &sfs}) *src = with_define(*src, "BB_NORMALS");
  if (d.parallax)  // and of the surface's plane offsets
    for (std::string* src : {&svs, &sfs}) *src = with_define(*src, "BB_OFFSET");
  if (Status st = shade_program(d.shade_snapshot, svs, sfs, "snapshot shader"); !st) return st.error();
  auto pc = program(d.layered ? layered(kClearVs) : std::string(kClearVs), kClearFs, "window clear shader");
  if (!pc) return pc.error();
  d.prog_clear = *pc;
  if (d.snapshot_samples > 1) {
    auto pr = program(d.layered ? layered(kClearVs) : std::string(kClearVs), kResolveFs, "snapshot resolve shader");
    if (!pr) return pr.error();
    d.prog_resolve = *pr;
  }
  {
    d.coverage_group = coverage_group_size(config.coverage_group, d.software);
    const std::string cov = with_define(kCoverageCs, "BB_GROUP", d.coverage_group);
    auto cs = compile(GL_COMPUTE_SHADER, d.parallax ? with_define(cov, "BB_OFFSETS") : cov, "coverage shader");
    if (!cs) return cs.error();
    auto pcov = link({*cs}, "coverage shader");
    if (!pcov) return pcov.error();
    d.prog_coverage = *pcov;
    glProgramUniform1f(d.prog_coverage, glGetUniformLocation(d.prog_coverage, "u_page"), static_cast<float>(config.page_size));
  }
  std::string bvs = kBillboardVs, bfs = kBillboardFs;
  d.depth_pass = d.parallax && config.parallax_depth_pass;
  if (d.parallax) {  // depth-corrected cards write their surface depth
    for (std::string* src : {&bvs, &bfs}) *src = with_define(*src, "BB_CARD_DEPTH");
    bfs = with_define(bfs, "BB_STEPS", std::clamp(config.parallax_steps, 0, 16));  // unrolled
  }
  if (d.relight)  // impostors lit as drawn
    for (std::string* src : {&bvs, &bfs}) *src = with_define(*src, "BB_RELIGHT");
  bfs = with_define(bfs, "BB_TAPS", d.snapshot_samples > 1 || config.impostor_taps <= 1 ? 1 : config.impostor_taps == 2 ? 2 : 4);
  {
    // Pulled quads read 7 texels each from one buffer texture: GL 4.5 promises 65,536 texels, Mesa
    // and the GPU drivers give 2^27 (19 million quads). Auto pulls only where 4 million fit.
    GLint max_texels = 0;
    glGetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &max_texels);
    d.max_pulled_quads = static_cast<std::size_t>(std::max(max_texels, 0)) / 7;
    constexpr std::size_t kPulledQuadsWanted = std::size_t{1} << 22;
    if (config.quad_fetch == 2 && d.max_pulled_quads < kPulledQuadsWanted)
      return Error{"", "ImpostorConfig::quad_fetch",
                   "pulled quads need a buffer texture of " + std::to_string(7 * kPulledQuadsWanted) + " texels; this GL gives " +
                       std::to_string(max_texels)};
    d.pull_quads = config.quad_fetch == 2 || (config.quad_fetch == 0 && d.software && d.max_pulled_quads >= kPulledQuadsWanted);
  }
  if (d.pull_quads) bvs = with_define(bvs, "BB_PULL");
  d.billboard_source = bvs + bfs;
  for (int mode = 0; mode < static_cast<int>(d.bb.size()); ++mode) {
    auto pb = program(bvs, mode == 3 ? with_define(bfs, "BB_PER_SAMPLE") : with_define(bfs, "BB_EDGES", mode),
                      (std::string("impostor shader (edges ") + std::to_string(mode) + ")").c_str());
    if (!pb) return pb.error();
    const GLuint prog = *pb;
    glProgramUniform1f(prog, glGetUniformLocation(prog, "u_half_texel"), 0.5f / static_cast<float>(config.page_size));
    d.bb[static_cast<std::size_t>(mode)] = {prog,
                                            glGetUniformLocation(prog, "u_viewproj"),
                                            glGetUniformLocation(prog, "u_eye"),
                                            glGetUniformLocation(prog, "u_up"),
                                            glGetUniformLocation(prog, "u_samples"),
                                            glGetUniformLocation(prog, "u_sample_pos"),
                                            glGetUniformLocation(prog, "u_depth_pass")};
  }
  d.upload_light();

  // Baked clips as a texture buffer.
  const auto rows = model.baked_palette();
  GLint max_texels = 0;
  glGetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &max_texels);
  if (rows.size() > static_cast<std::size_t>(max_texels))
    return Error{model.name, "clips", "the baked clips need " + std::to_string(rows.size()) + " texels, the GPU allows " +
                                          std::to_string(max_texels) + " (bake at a lower rate)"};
  glCreateBuffers(1, &d.palette_buffer);
  glNamedBufferStorage(d.palette_buffer, static_cast<GLsizeiptr>(std::max<std::size_t>(1, rows.size()) * sizeof(glm::vec4)),
                       rows.empty() ? nullptr : rows.data(), 0);
  glCreateTextures(GL_TEXTURE_BUFFER, 1, &d.palette_texture);
  glTextureBuffer(d.palette_texture, GL_RGBA32F, d.palette_buffer);

  // Textures (mipmapped), and a white one for untextured materials.
  auto make_texture = [](int w, int h, const std::uint8_t* px) {
    GLuint t;
    glCreateTextures(GL_TEXTURE_2D, 1, &t);
    int levels = 1;
    while ((std::max(w, h) >> levels) > 0) ++levels;
    glTextureStorage2D(t, levels, GL_RGBA8, w, h);
    glTextureSubImage2D(t, 0, 0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, px);
    glGenerateTextureMipmap(t);
    glTextureParameteri(t, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
    glTextureParameteri(t, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTextureParameteri(t, GL_TEXTURE_WRAP_S, GL_REPEAT);
    glTextureParameteri(t, GL_TEXTURE_WRAP_T, GL_REPEAT);
    return t;
  };
  const std::uint8_t white[4] = {255, 255, 255, 255};
  d.white = make_texture(1, 1, white);
  for (const Texture& t : model.textures) d.textures.push_back(make_texture(t.width, t.height, t.rgba.data()));
  // One sampler object per material (the glTF sampler its texture names), bound with its texture.
  for (const Material& m : model.materials) {
    const TextureSampler& ts = m.sampler;
    GLuint s;
    glCreateSamplers(1, &s);
    auto wrap = [](Wrap w) {
      return w == Wrap::kClampToEdge ? GL_CLAMP_TO_EDGE : w == Wrap::kMirroredRepeat ? GL_MIRRORED_REPEAT : GL_REPEAT;
    };
    const GLenum min = !ts.mipmaps     ? (ts.min_nearest ? GL_NEAREST : GL_LINEAR)
                       : ts.mip_nearest ? (ts.min_nearest ? GL_NEAREST_MIPMAP_NEAREST : GL_LINEAR_MIPMAP_NEAREST)
                                        : (ts.min_nearest ? GL_NEAREST_MIPMAP_LINEAR : GL_LINEAR_MIPMAP_LINEAR);
    glSamplerParameteri(s, GL_TEXTURE_WRAP_S, static_cast<GLint>(wrap(ts.wrap_s)));
    glSamplerParameteri(s, GL_TEXTURE_WRAP_T, static_cast<GLint>(wrap(ts.wrap_t)));
    glSamplerParameteri(s, GL_TEXTURE_MAG_FILTER, ts.mag_nearest ? GL_NEAREST : GL_LINEAR);
    glSamplerParameteri(s, GL_TEXTURE_MIN_FILTER, static_cast<GLint>(min));
    d.samplers.push_back(s);
  }

  glCreateBuffers(1, &d.instances.id);
  glCreateBuffers(1, &d.snapshots.id);
  glCreateBuffers(1, &d.billboards.id);
  d.instances.capacity = d.snapshots.capacity = d.billboards.capacity = 4096;
  for (StreamBuffer* b : {&d.instances, &d.snapshots, &d.billboards})
    glNamedBufferData(b->id, static_cast<GLsizeiptr>(b->capacity), nullptr, GL_STREAM_DRAW);

  auto vertex_format = [](GLuint vao, GLuint vbo, GLuint ibo) {
    glVertexArrayVertexBuffer(vao, 0, vbo, 0, sizeof(Vertex));
    glVertexArrayElementBuffer(vao, ibo);
    const GLuint offs[5] = {offsetof(Vertex, position), offsetof(Vertex, normal), offsetof(Vertex, uv),
                            offsetof(Vertex, joints), offsetof(Vertex, weights)};
    for (GLuint a : {0u, 1u, 2u, 3u, 4u, 15u}) {
      glEnableVertexArrayAttrib(vao, a);
      glVertexArrayAttribBinding(vao, a, 0);
    }
    glVertexArrayAttribFormat(vao, 0, 3, GL_FLOAT, GL_FALSE, offs[0]);
    glVertexArrayAttribFormat(vao, 1, 3, GL_FLOAT, GL_FALSE, offs[1]);
    glVertexArrayAttribFormat(vao, 2, 2, GL_FLOAT, GL_FALSE, offs[2]);
    glVertexArrayAttribIFormat(vao, 3, 4, GL_UNSIGNED_SHORT, offs[3]);
    glVertexArrayAttribFormat(vao, 4, 4, GL_FLOAT, GL_FALSE, offs[4]);
    glVertexArrayAttribFormat(vao, 15, 4, GL_UNSIGNED_BYTE, GL_TRUE, offsetof(Vertex, color));  // BB_COLORED's a_color
  };
  auto instance_attribs = [](GLuint vao, GLuint buffer, GLsizei stride, GLuint first_attr, GLuint count) {
    glVertexArrayVertexBuffer(vao, 1, buffer, 0, stride);
    glVertexArrayBindingDivisor(vao, 1, 1);
    for (GLuint k = 0; k < count; ++k) {
      glEnableVertexArrayAttrib(vao, first_attr + k);
      glVertexArrayAttribBinding(vao, first_attr + k, 1);
      glVertexArrayAttribFormat(vao, first_attr + k, 4, GL_FLOAT, GL_FALSE, k * 16);
    }
  };
  d.parts = static_cast<int>(model.body_parts().size());
  for (const MeshLod& ml : model.lods) {
    Impl::Lod l;
    // The level's vertices, then its part caps' (PartIndices::cap_vertices).
    const std::vector<Vertex>* vertices = &ml.vertices;
    std::vector<Vertex> with_caps;
    if (d.parts > 1) {
      const std::vector<Vertex>& caps = model.part_indices(static_cast<int>(d.lods.size())).cap_vertices;
      if (!caps.empty()) {
        with_caps.reserve(ml.vertices.size() + caps.size());
        with_caps.insert(with_caps.end(), ml.vertices.begin(), ml.vertices.end());
        with_caps.insert(with_caps.end(), caps.begin(), caps.end());
        vertices = &with_caps;
      }
    }
    glCreateBuffers(1, &l.vbo);
    glNamedBufferStorage(l.vbo, static_cast<GLsizeiptr>(vertices->size() * sizeof(Vertex)), vertices->data(), 0);
    glCreateBuffers(1, &l.ibo);
    glNamedBufferStorage(l.ibo, static_cast<GLsizeiptr>(ml.indices.size() * 4), ml.indices.data(), 0);
    glCreateVertexArrays(1, &l.vao_geometry);
    vertex_format(l.vao_geometry, l.vbo, l.ibo);
    instance_attribs(l.vao_geometry, d.instances.id, sizeof(InstanceGpu), 5, 2);
    glCreateVertexArrays(1, &l.vao_snapshot);
    vertex_format(l.vao_snapshot, l.vbo, l.ibo);
    instance_attribs(l.vao_snapshot, d.snapshots.id, sizeof(SnapshotGpu), 5, 9);
    if (d.parts > 1) {
      const PartIndices& pi = model.part_indices(static_cast<int>(d.lods.size()));
      glCreateBuffers(1, &l.part_ibo);
      glNamedBufferStorage(l.part_ibo, static_cast<GLsizeiptr>(std::max<std::size_t>(1, pi.indices.size()) * 4),
                           pi.indices.empty() ? nullptr : pi.indices.data(), 0);
      glCreateVertexArrays(1, &l.vao_part_snapshot);
      vertex_format(l.vao_part_snapshot, l.vbo, l.part_ibo);
      instance_attribs(l.vao_part_snapshot, d.snapshots.id, sizeof(SnapshotGpu), 5, 9);
    }
    d.lods.push_back(l);
  }
  glCreateVertexArrays(1, &d.vao_billboard);
  instance_attribs(d.vao_billboard, d.billboards.id, sizeof(BillboardGpu), 0, 7);
  glCreateBuffers(1, &d.quad_indices);  // pulled quads' (fit_pulled_quads fills it)
  glVertexArrayElementBuffer(d.vao_billboard, d.quad_indices);

  // The atlas: one RGBA8 layer per page, one depth buffer shared by all pages; this renderer's or
  // share_atlas's (whose pages this model's planner takes a part of: ImpostorConfig::first_page).
  const int smallest_window = std::max(1, config.windows.size[std::max(0, config.windows.count - 1)]);
  const int atlas_pages = config.atlas_pages > 0 ? config.atlas_pages : config.max_pages;
  if (config.first_page < 0 || config.max_pages < 1 || config.first_page + config.max_pages > atlas_pages)
    return Error{"", "atlas", "pages " + std::to_string(config.first_page) + " to " +
                                  std::to_string(config.first_page + config.max_pages - 1) + " do not lie in an atlas of " +
                                  std::to_string(atlas_pages) + " pages"};
  if (share_atlas) {
    const AtlasGl& a = *share_atlas->impl_->shared_atlas;
    if (a.page_size != config.page_size || a.pages != atlas_pages || a.smallest_window != smallest_window ||
        a.layered != d.layered || a.relight != d.relight || a.parallax != d.parallax)
      return Error{"", "atlas", "the atlas to share was made for another page size, number of pages, smallest window or "
                                "kind of snapshot (relit, depth-corrected) than this config's"};
    d.shared_atlas = share_atlas->impl_->shared_atlas;
  } else {
    GLint max_layers = 0, max_size = 0;
    glGetIntegerv(GL_MAX_ARRAY_TEXTURE_LAYERS, &max_layers);
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
    if (config.page_size > max_size || atlas_pages > max_layers)
      return Error{"", "atlas", "page size " + std::to_string(config.page_size) + " x " + std::to_string(atlas_pages) +
                                    " pages exceeds the GPU's limits (" + std::to_string(max_size) + ", " +
                                    std::to_string(max_layers) + " layers)"};
    auto made = std::make_shared<AtlasGl>();
    AtlasGl& a = *made;
    a.layered = d.layered;
    a.relight = d.relight;
    a.parallax = d.parallax;
    a.page_size = config.page_size;
    a.pages = atlas_pages;
    a.smallest_window = smallest_window;
    // One layer per page (at 1 / `reduce` of the page's size), clamped at the edges.
    auto page_array = [&](GLenum format, GLint filter, int reduce = 1) {
      GLuint t = 0;
      glCreateTextures(GL_TEXTURE_2D_ARRAY, 1, &t);
      glTextureStorage3D(t, 1, format, config.page_size / reduce, config.page_size / reduce, atlas_pages);
      glTextureParameteri(t, GL_TEXTURE_MIN_FILTER, filter);
      glTextureParameteri(t, GL_TEXTURE_MAG_FILTER, filter);
      glTextureParameteri(t, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
      glTextureParameteri(t, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
      return t;
    };
    while (glGetError() != GL_NO_ERROR) {
    }
    a.atlas = page_array(GL_RGBA8, GL_LINEAR);
    glCreateFramebuffers(1, &a.atlas_fbo);
    if (a.layered) {
      a.atlas_depth = page_array(GL_DEPTH_COMPONENT24, GL_NEAREST);
      glNamedFramebufferTexture(a.atlas_fbo, GL_COLOR_ATTACHMENT0, a.atlas, 0);
      glNamedFramebufferTexture(a.atlas_fbo, GL_DEPTH_ATTACHMENT, a.atlas_depth, 0);
      if (a.relight) {
        // Normals at 8 bits a component: the same PSNR as 10 (RGB10_A2) on the flow test bed, and
        // 20 % less time for the relit cards on llvmpipe.
        a.atlas_normal = page_array(GL_RGBA8, GL_LINEAR);
        glNamedFramebufferTexture(a.atlas_fbo, GL_COLOR_ATTACHMENT1, a.atlas_normal, 0);
      }
      if (a.parallax) {
        // Half floats: offsets of a few half sizes, to ~1e-3 of one.
        a.atlas_offset = page_array(GL_RG16F, GL_LINEAR);
        glNamedFramebufferTexture(a.atlas_fbo, GL_COLOR_ATTACHMENT2, a.atlas_offset, 0);
        a.atlas_offset_wide = page_array(GL_RG16F, GL_LINEAR, 4);
      }
      if (a.relight || a.parallax) {
        const GLenum none = GL_NONE;
        const GLenum bufs[3] = {GL_COLOR_ATTACHMENT0, a.relight ? GLenum{GL_COLOR_ATTACHMENT1} : none,
                                a.parallax ? GLenum{GL_COLOR_ATTACHMENT2} : none};
        glNamedFramebufferDrawBuffers(a.atlas_fbo, 3, bufs);
      }
    } else {
      glCreateRenderbuffers(1, &a.atlas_depth);
      glNamedRenderbufferStorage(a.atlas_depth, GL_DEPTH_COMPONENT24, config.page_size, config.page_size);
      glNamedFramebufferTextureLayer(a.atlas_fbo, GL_COLOR_ATTACHMENT0, a.atlas, 0, 0);
      glNamedFramebufferRenderbuffer(a.atlas_fbo, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, a.atlas_depth);
    }
    if (glGetError() == GL_OUT_OF_MEMORY)  // llvmpipe makes no texture over 2 GB: 512 pages of 1024
      return Error{"", "atlas", std::to_string(atlas_pages) + " pages of " + std::to_string(config.page_size) + " x " +
                                    std::to_string(config.page_size) + " texels are more than the GL makes in one texture"};
    if (glCheckNamedFramebufferStatus(a.atlas_fbo, GL_DRAW_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      return Error{"", "atlas", "the atlas framebuffer is incomplete"};
    // Quads fitted to the coverage: a rectangle per smallest-window slot of every page; until a
    // window's first fitted snapshot, the whole window (the planner's quad is drawn).
    const int per_row = config.page_size / smallest_window;
    glCreateBuffers(1, &a.coverage);
    const std::vector<glm::vec4> whole(static_cast<std::size_t>(atlas_pages) * per_row * per_row, glm::vec4(-1.0f, -1.0f, 1.0f, 1.0f));
    glNamedBufferStorage(a.coverage, static_cast<GLsizeiptr>(whole.size() * sizeof(glm::vec4)), whole.data(), 0);
    d.shared_atlas = std::move(made);
  }
  if (d.snapshot_samples > 1) {
    GLint max_samples = 1;
    glGetIntegerv(GL_MAX_SAMPLES, &max_samples);
    d.snapshot_samples = std::min(d.snapshot_samples, std::max(1, static_cast<int>(max_samples)));
    glProgramUniform1i(d.prog_resolve, glGetUniformLocation(d.prog_resolve, "u_samples"), d.snapshot_samples);
    glCreateTextures(GL_TEXTURE_2D_MULTISAMPLE, 1, &d.scratch_color);
    glTextureStorage2DMultisample(d.scratch_color, d.snapshot_samples, GL_RGBA8, config.page_size, config.page_size, GL_TRUE);
    glCreateRenderbuffers(1, &d.scratch_depth);
    glNamedRenderbufferStorageMultisample(d.scratch_depth, d.snapshot_samples, GL_DEPTH_COMPONENT24, config.page_size,
                                          config.page_size);
    glCreateFramebuffers(1, &d.scratch_fbo);
    glNamedFramebufferTexture(d.scratch_fbo, GL_COLOR_ATTACHMENT0, d.scratch_color, 0);
    glNamedFramebufferRenderbuffer(d.scratch_fbo, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, d.scratch_depth);
    if (glCheckNamedFramebufferStatus(d.scratch_fbo, GL_DRAW_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      return Error{"", "atlas", "the multisampled snapshot framebuffer is incomplete"};
  }
  if (GLenum e = glGetError(); e != GL_NO_ERROR)
    return Error{"", "GL", "error 0x" + std::to_string(e) + " while uploading the model"};
  return r;
}

Renderer::~Renderer() {
  if (!impl_) return;
  Impl& d = *impl_;
  if (d.stamps[0]) glDeleteQueries(5, d.stamps.data());
  for (auto& l : d.lods) {
    glDeleteVertexArrays(1, &l.vao_geometry);
    glDeleteVertexArrays(1, &l.vao_snapshot);
    if (l.part_ibo) {
      glDeleteVertexArrays(1, &l.vao_part_snapshot);
      glDeleteBuffers(1, &l.part_ibo);
    }
    glDeleteBuffers(1, &l.vbo);
    glDeleteBuffers(1, &l.ibo);
  }
  glDeleteVertexArrays(1, &d.vao_billboard);
  glDeleteTextures(1, &d.quad_texture);
  glDeleteBuffers(1, &d.quad_indices);
  if (!d.textures.empty()) glDeleteTextures(static_cast<GLsizei>(d.textures.size()), d.textures.data());
  if (!d.samplers.empty()) glDeleteSamplers(static_cast<GLsizei>(d.samplers.size()), d.samplers.data());
  glDeleteTextures(1, &d.white);
  glDeleteTextures(1, &d.palette_texture);
  glDeleteBuffers(1, &d.palette_buffer);
  for (GLuint b : {d.instances.id, d.snapshots.id, d.billboards.id}) glDeleteBuffers(1, &b);
  d.shared_atlas.reset();  // the atlas's objects go with the last renderer that draws into it
  glDeleteProgram(d.prog_coverage);
  if (d.scratch_fbo) {
    glDeleteFramebuffers(1, &d.scratch_fbo);
    glDeleteTextures(1, &d.scratch_color);
    glDeleteRenderbuffers(1, &d.scratch_depth);
    glDeleteProgram(d.prog_resolve);
  }
  for (const Impl::ShadeProgram* sp : {&d.shade_geometry, &d.shade_snapshot})
    for (GLuint p : sp->prog) glDeleteProgram(p);
  glDeleteProgram(d.prog_clear);
  for (const Impl::BillboardProgram& b : d.bb) glDeleteProgram(b.prog);
}

void Renderer::set_light(glm::vec3 towards_light) {
  Impl& d = *impl_;
  const float len = glm::length(towards_light);
  if (!(len > 0.0f) || !std::isfinite(len)) return;  // no direction: keep the light
  d.light = towards_light / len;
  d.upload_light();
}

void Renderer::draw(const FramePlan& plan, const DrawOptions& options) {
  Impl& d = *impl_;
  glBindTextureUnit(0, d.palette_texture);
  glDisable(GL_CULL_FACE);
  d.culling = false;
  glCullFace(GL_BACK);
  glFrontFace(GL_CCW);
  glDisable(GL_BLEND);
  glEnable(GL_DEPTH_TEST);
  glDepthMask(GL_TRUE);
  glDepthFunc(GL_LESS);

  d.flush_auto = options.flush_every_indices < 0;
  d.flush_every = static_cast<std::size_t>(
      d.flush_auto ? (d.software ? kSoftwareFlushIndices : 0) : options.flush_every_indices);
  d.flush_at = 0;
  const bool ts = options.time_stages;
  if (ts && d.stamps[0] == 0) glCreateQueries(GL_TIMESTAMP, 5, d.stamps.data());
  d.stamped = ts;
  d.stamp(ts, 0);
  // 1. Snapshots due (section 4: shared pages, few passes), then their coverage rectangles.
  if (options.take_snapshots) {
    // The plan's quads show snapshots of its planner's cache: where this renderer did not take them
    // (a renderer made anew without FramePlanner::invalidate()), its windows are empty this frame, and
    // the planner is told to take them all anew at its next frame.
    if (!plan.billboards.empty() && !holds_snapshots_for(plan)) plan.drawn_from_another_atlas = true;
    if (std::any_of(plan.snapshots.begin(), plan.snapshots.end(), [](const auto& s) { return !s.empty(); }))
      d.cache_id = plan.cache_id;
    d.take_snapshots(plan, ts);
  } else {  // no snapshot stage: its stamps now, not a previous frame's
    d.stamp(ts, 1);
    d.stamp(ts, 2);
  }
  glViewport(0, 0, plan.camera.width, plan.camera.height);
  const glm::mat4 viewproj = plan.camera.projection() * plan.camera.view();

  // 2. Geometry: one instanced draw per LOD level and primitive.
  if (options.draw_geometry) {
    d.instance_scratch.clear();
    d.instance_lod.clear();
    for (std::size_t lod = 0; lod < plan.geometry.size() && lod < d.lods.size(); ++lod) {
      d.instance_scratch.insert(d.instance_scratch.end(), plan.geometry[lod].begin(), plan.geometry[lod].end());
      if (d.any_blended) d.instance_lod.insert(d.instance_lod.end(), plan.geometry[lod].size(), static_cast<int>(lod));
    }
    const std::size_t n_instances = d.instance_scratch.size();
    if (n_instances > 0 && d.any_blended) {
      // The blended surfaces are drawn character by character from the farthest to the nearest
      // (the distance along the view direction of the origin raised by Ta's height, times the
      // scale), so that each lies over those behind it. The instances go again after the first
      // copy in that order, and each run of one level is one draw.
      const glm::vec3 fwd = glm::normalize(plan.camera.target - plan.camera.eye);
      d.blend_depth.resize(n_instances);
      for (std::size_t i = 0; i < n_instances; ++i) {
        const InstanceGpu& g = d.instance_scratch[i];
        const glm::vec3 centre = glm::vec3(g.position_yaw) + glm::vec3(0.0f, d.model->ta.y * g.anim.x, 0.0f);
        d.blend_depth[i] = -glm::dot(centre - plan.camera.eye, fwd);
      }
      d.depth_order.sort(d.blend_depth, d.blend_order);
      d.instance_scratch.reserve(2 * n_instances);
      for (std::size_t k = 0; k < n_instances; ++k) d.instance_scratch.push_back(d.instance_scratch[d.blend_order[k]]);
    }
    if (n_instances > 0) {
      d.instances.upload(d.instance_scratch.data(), d.instance_scratch.size() * sizeof(InstanceGpu));
      for (std::size_t v = 0; v < Impl::kShadeVariants; ++v)
        if (d.shade_geometry.prog[v])
          glProgramUniformMatrix4fv(d.shade_geometry.prog[v], d.shade_geometry.viewproj[v], 1, GL_FALSE, glm::value_ptr(viewproj));
      GLuint base = 0;
      d.flushes_for_bound_target(
          [&] {
            std::size_t n = 0;
            for (std::size_t lod = 0; lod < plan.geometry.size() && lod < d.lods.size(); ++lod)
              n += plan.geometry[lod].size() * d.instance_indices(static_cast<int>(lod), -1);
            return n;
          },
          2);
      // Every character's opaque surfaces, then (where the model has any) its alpha-blended ones
      // over them, back to front (the triangles within one character are not sorted).
      for (std::size_t lod = 0; lod < plan.geometry.size() && lod < d.lods.size(); ++lod) {
        const GLsizei count = static_cast<GLsizei>(plan.geometry[lod].size());
        if (count == 0) continue;
        glBindVertexArray(d.lods[lod].vao_geometry);
        d.draw_lod(d.shade_geometry, static_cast<int>(lod), count, base, Impl::Surfaces::kOpaque);
        base += static_cast<GLuint>(count);
      }
      for (std::size_t b = 0; d.any_blended && b < n_instances;) {
        const int lod = d.instance_lod[d.blend_order[b]];
        std::size_t e = b + 1;
        while (e < n_instances && d.instance_lod[d.blend_order[e]] == lod) ++e;
        glBindVertexArray(d.lods[static_cast<std::size_t>(lod)].vao_geometry);
        d.draw_lod(d.shade_geometry, lod, static_cast<GLsizei>(e - b), static_cast<GLuint>(n_instances + b),
                   Impl::Surfaces::kBlended);
        b = e;
      }
    }
  }

  d.stamp(ts, 3);
  d.set_culling(false);  // the quads, and the state draw() leaves
  // 3. Impostors: camera-facing quads, one instanced draw.
  if (options.draw_impostors && !plan.billboards.empty()) {
    const Impl::ImpostorPass p = d.impostor_pass(options.edges, plan.stats.part_cards > 0);
    if (p.mode == 1) {
      // Blending: back to front (distance of Ta along the view direction), so that soft edges
      // fall on what lies behind them.
      d.order_back_to_front(plan);
      d.write_impostors(p, plan, d.billboard_order.size(), viewproj, [&](BillboardGpu* out) {
        for (std::size_t k = 0; k < d.billboard_order.size(); ++k) out[k] = plan.billboards[d.billboard_order[k]];
      });
    } else {
      d.upload_impostors(p, plan, plan.billboards.data(), plan.billboards.size(), viewproj);
    }
    d.bind_impostors(p);
    const bool single_sampled = Impl::begin_impostor_state(p.mode);
    d.draw_impostor_range(p, 0, static_cast<GLsizei>(plan.billboards.size()));
    Impl::end_impostor_state(single_sampled);
  }
  d.stamp(ts, 4);
  Impl::end_draw();
}

void Renderer::draw_many(std::span<Renderer* const> renderers, std::span<const FramePlan* const> plans,
                         const DrawOptions& options) {
  const std::size_t n = std::min(renderers.size(), plans.size());
  assert(renderers.size() == plans.size());
  if (n == 1 || options.time_stages) {
    for (std::size_t k = 0; k < n; ++k) renderers[k]->draw(*plans[k], options);
    return;
  }
  if (n == 0) return;
  // Snapshots, then geometry (each pass of several models in one go: a snapshot pass between two
  // models' quads would make llvmpipe finish the frame's drawing so far, since it flushes on each
  // change of framebuffer).
  DrawOptions snap = options, geo = options, imp = options;
  snap.draw_geometry = snap.draw_impostors = false;
  geo.take_snapshots = geo.draw_impostors = false;
  imp.take_snapshots = imp.draw_geometry = false;
  if (options.take_snapshots)
    for (std::size_t k = 0; k < n; ++k) renderers[k]->draw(*plans[k], snap);
  if (options.draw_geometry)
    for (std::size_t k = 0; k < n; ++k) renderers[k]->draw(*plans[k], geo);
  if (!options.draw_impostors) return;
  std::size_t with_quads = 0, first = n;
  for (std::size_t k = 0; k < n; ++k)
    if (!plans[k]->billboards.empty()) {
      ++with_quads;
      first = std::min(first, k);
    }
  if (with_quads == 0) return;
  if (options.edges != ImpostorEdges::kBlend || with_quads == 1) {
    // Without blending the depth test orders the quads whatever the draw order.
    for (std::size_t k = 0; k < n; ++k)
      if (!plans[k]->billboards.empty()) renderers[k]->draw(*plans[k], imp);
    return;
  }
  Impl& d0 = *renderers[first]->impl_;
  const SceneCamera& camera = plans[first]->camera;
  const glm::mat4 viewproj = camera.projection() * camera.view();
  const glm::vec3 fwd = glm::normalize(camera.target - camera.eye);
  // Renderers whose impostor programs are alike (the same config and kind of quads, and the same
  // light where they relight) draw with the first one's: on llvmpipe a change of program costs each
  // draw after it its own state validation. Those that also share one atlas draw every model's
  // quads in one upload, back to front (ties in model, then plan order), and one draw.
  bool alike = true, one_atlas = true;
  for (std::size_t k = first + 1; k < n; ++k) {
    const Impl& d = *renderers[k]->impl_;
    if (plans[k]->billboards.empty()) continue;
    alike = alike && d.billboard_source == d0.billboard_source &&
            (plans[k]->stats.part_cards > 0) == (plans[first]->stats.part_cards > 0) && d.depth_pass == d0.depth_pass &&
            (!d.relight || d.light == d0.light);
    one_atlas = one_atlas && d.shared_atlas == d0.shared_atlas;
  }
  if (alike && one_atlas) {
    // Each quad's key, in model then plan order; a quad's model (many_model) and its place in
    // the plan (its place here less its model's first) name it after the sort.
    d0.many_first.resize(n + 1);
    d0.many_first[0] = 0;
    for (std::size_t k = 0; k < n; ++k) d0.many_first[k + 1] = d0.many_first[k] + static_cast<std::uint32_t>(plans[k]->billboards.size());
    d0.many_depth.resize(d0.many_first[n]);
    d0.many_model.resize(d0.many_first[n]);
    for (std::size_t k = 0; k < n; ++k) {
      const std::vector<BillboardGpu>& quads = plans[k]->billboards;
      float* depth = d0.many_depth.data() + d0.many_first[k];
      for (std::size_t i = 0; i < quads.size(); ++i) depth[i] = -glm::dot(glm::vec3(quads[i].ta_half) - camera.eye, fwd);
      std::fill_n(d0.many_model.data() + d0.many_first[k], quads.size(), static_cast<std::uint32_t>(k));
    }
    d0.depth_order.sort(d0.many_depth, d0.many_order);
    Impl::begin_many_impostors(camera);
    const Impl::ImpostorPass p = Impl::impostor_pass(options.edges, plans[first]->stats.part_cards > 0);
    const std::size_t count = d0.many_order.size();
    d0.write_impostors(p, *plans[first], count, viewproj, [&](BillboardGpu* out) {
      for (std::size_t j = 0; j < count; ++j) {
        const std::uint32_t g = d0.many_order[j], k = d0.many_model[g];
        out[j] = plans[k]->billboards[g - d0.many_first[k]];
      }
    });
    d0.bind_impostors(p);
    const bool single_sampled = Impl::begin_impostor_state(p.mode);
    d0.draw_impostor_range(p, 0, static_cast<GLsizei>(count));
    Impl::end_impostor_state(single_sampled);
    Impl::end_draw();
    return;
  }
  // Else every model's quads back to front (ties in model, then plan order), on screen, in layers.
  d0.many_quads.clear();
  d0.many_depth.clear();
  d0.many_index.clear();  // each quad's index in its plan (its model: many_quads[g].model)
  // Quads under kLayerMinPixels high (part cards: kLayerMinCardPixels) are not placed on screen:
  // they go first, in layer 0 (far away as they mostly are), and the others from layer 1 on. A
  // crowd of 10,000 then keeps a draw a model (flow test bed, our four bodies: 8 layers and 32 draws cost 5-6 ms a frame on
  // llvmpipe, for the same pictures to 0.001 dB).
  bool any_small = false;
  for (std::size_t k = 0; k < n; ++k) {
    const float min_pixels = plans[k]->stats.part_cards > 0 ? kLayerMinCardPixels : kLayerMinPixels;
    for (std::size_t i = 0; i < plans[k]->billboards.size(); ++i) {
      const BillboardGpu& b = plans[k]->billboards[i];
      const float depth = glm::dot(glm::vec3(b.ta_half) - camera.eye, fwd);
      const bool small = depth > camera.near_plane &&
                         (b.rect.w - b.rect.y) * b.ta_half.w * camera.pixels_per_metre(depth) < min_pixels;
      any_small = any_small || small;
      d0.many_quads.push_back(
          LayerQuad{static_cast<int>(k), small ? glm::vec4(0.0f) : quad_screen_rect(b, camera, viewproj), small ? 0 : 1});
      d0.many_depth.push_back(-depth);
      d0.many_index.push_back(static_cast<std::uint32_t>(i));
    }
  }
  if (!any_small)
    for (LayerQuad& q : d0.many_quads) q.min_layer = 0;
  std::vector<std::uint32_t>& order = d0.many_order;
  d0.depth_order.sort(d0.many_depth, order);
  const int layers = d0.layering.assign(d0.many_quads, order, camera.width, camera.height, kMaxImpostorLayers, d0.many_layer);
  // Each renderer's quads by layer, back to front within one, and its ranges: counted, then put in
  // place, one pass over the quads each whatever the number of layers (a pass a layer cost 0.27 ms a
  // frame of the 10,000-human flow test bed's on this 2-core machine; the GPU's frame there is 2 ms).
  for (std::size_t k = 0; k < n; ++k) renderers[k]->impl_->layer_ranges.assign(static_cast<std::size_t>(layers), {0, 0});
  for (std::uint32_t g : order) {
    Impl& d = *renderers[static_cast<std::size_t>(d0.many_quads[g].model)]->impl_;
    ++d.layer_ranges[static_cast<std::size_t>(d0.many_layer[g])][1];
  }
  for (std::size_t k = 0; k < n; ++k) {
    Impl& d = *renderers[k]->impl_;
    GLuint at = 0;
    d.layer_next.resize(d.layer_ranges.size());
    for (std::size_t l = 0; l < d.layer_ranges.size(); ++l) {
      d.layer_ranges[l][0] = d.layer_next[l] = at;
      at += d.layer_ranges[l][1];
    }
    d.billboard_scratch.resize(at);
  }
  for (std::uint32_t g : order) {
    const std::size_t k = static_cast<std::size_t>(d0.many_quads[g].model);
    Impl& d = *renderers[k]->impl_;
    d.billboard_scratch[d.layer_next[static_cast<std::size_t>(d0.many_layer[g])]++] = plans[k]->billboards[d0.many_index[g]];
  }
  Impl::begin_many_impostors(camera);
  std::vector<Impl::ImpostorPass>& pass = d0.many_pass;  // one framebuffer: one mode; cards per plan
  pass.assign(n, Impl::impostor_pass(options.edges, false));
  for (std::size_t k = 0; k < n; ++k) {
    Impl& d = *renderers[k]->impl_;
    if (d.billboard_scratch.empty()) continue;
    pass[k].cards = plans[k]->stats.part_cards > 0;
    d.upload_impostors(pass[k], *plans[k], d.billboard_scratch.data(), d.billboard_scratch.size(), viewproj);
  }
  // Alike programs: a change of renderer between two draws binds only its atlas and quads.
  const bool single_sampled = Impl::begin_impostor_state(1);
  if (alike) glUseProgram(d0.bb[static_cast<std::size_t>(pass[first].mode)].prog);
  std::size_t bound = n;
  for (int layer = 0; layer < layers; ++layer)
    for (std::size_t k = 0; k < n; ++k) {
      Impl& d = *renderers[k]->impl_;
      if (d.billboard_scratch.empty()) continue;
      const auto& range = d.layer_ranges[static_cast<std::size_t>(layer)];
      if (range[1] == 0) continue;
      if (bound != k) {
        d.bind_impostors(pass[k], !alike);
        bound = k;
      }
      (alike ? d0 : d).draw_impostor_range(pass[k], range[0], static_cast<GLsizei>(range[1]));
    }
  Impl::end_impostor_state(single_sampled);
  Impl::end_draw();
}

StageTimes Renderer::stage_times() const {
  const Impl& d = *impl_;
  StageTimes t;
  if (!d.stamped) return t;
  std::array<GLuint64, 5> ns{};
  for (int k = 0; k < 5; ++k) glGetQueryObjectui64v(d.stamps[k], GL_QUERY_RESULT, &ns[k]);
  auto ms = [&](int a, int b) { return ns[b] >= ns[a] ? static_cast<double>(ns[b] - ns[a]) * 1e-6 : 0.0; };
  t.snapshots = ms(0, 1);
  t.coverage = ms(1, 2);
  t.geometry = ms(2, 3);
  t.impostors = ms(3, 4);
  t.valid = true;
  return t;
}

std::vector<std::uint8_t> Renderer::read_atlas_page(int page) const {
  const int s = impl_->config.page_size;
  std::vector<std::uint8_t> px(static_cast<std::size_t>(s) * s * 4);
  glGetTextureSubImage(impl_->shared_atlas->atlas, 0, 0, 0, page, s, s, 1, GL_RGBA, GL_UNSIGNED_BYTE, static_cast<GLsizei>(px.size()),
                       px.data());
  return px;
}

int Renderer::coverage_group() const { return impl_->coverage_group; }
bool Renderer::pulls_quads() const { return impl_->pull_quads; }

glm::vec4 Renderer::coverage_rect(int slot) const {
  glm::vec4 r(0.0f);
  glGetNamedBufferSubData(impl_->shared_atlas->coverage, static_cast<GLintptr>(slot) * 16, 16, &r);
  return r;
}

double Renderer::drawn_quad_texels(const FramePlan& plan) const {
  const float page = static_cast<float>(impl_->config.page_size);
  // One read of the rectangles the plan's fitted quads use.
  int slots = 0;
  for (const BillboardGpu& b : plan.billboards)
    if (b.layer.z > 0.5f) slots = std::max(slots, static_cast<int>(b.layer.y) + 1);
  std::vector<glm::vec4> covered(static_cast<std::size_t>(slots));
  if (slots > 0)
    glGetNamedBufferSubData(impl_->shared_atlas->coverage, 0, static_cast<GLsizeiptr>(covered.size() * sizeof(glm::vec4)), covered.data());
  double texels = 0;
  for (const BillboardGpu& b : plan.billboards) {
    glm::vec4 r = b.rect;
    if (b.layer.z > 0.5f) {
      const glm::vec4 f = covered[static_cast<std::size_t>(b.layer.y)];
      r = glm::vec4(glm::max(glm::vec2(r), glm::vec2(f)), glm::min(glm::vec2(r.z, r.w), glm::vec2(f.z, f.w)));
    }
    const double half = 0.5 * static_cast<double>(b.uv_rect.z - b.uv_rect.x) * page;  // window size / 2
    if (r.z > r.x && r.w > r.y) texels += (r.z - r.x) * half * (r.w - r.y) * half;
  }
  return texels;
}

bool software_rasterizer() {
  const char* name = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  return name && (std::strstr(name, "llvmpipe") || std::strstr(name, "softpipe"));
}

int impostor_target_samples(ImpostorEdges edges, int scene_samples) {
  switch (edges) {
    case ImpostorEdges::kBlend:
      return 1;
    case ImpostorEdges::kSamples:
    case ImpostorEdges::kAlphaToCoverage:
    case ImpostorEdges::kAlphaTest:
    case ImpostorEdges::kCentre:
      break;
  }
  return std::max(1, scene_samples);
}

Result<std::unique_ptr<OffscreenTarget>> OffscreenTarget::create(int width, int height, int samples) {
  if (width <= 0 || height <= 0 || width > 16384 || height > 16384)
    return Error{"", "target", "size " + std::to_string(width) + "x" + std::to_string(height) + " is out of range"};
  std::unique_ptr<OffscreenTarget> t(new OffscreenTarget());
  t->width_ = width;
  t->height_ = height;
  GLint max_samples = 1;
  glGetIntegerv(GL_MAX_SAMPLES, &max_samples);
  t->samples_ = std::clamp(samples, 1, std::max(1, max_samples));
  const GLsizei ms = t->samples_ > 1 ? t->samples_ : 0;
  glCreateRenderbuffers(1, &t->color_);
  glNamedRenderbufferStorageMultisample(t->color_, ms, GL_RGBA8, width, height);
  // The driver may give more samples than asked (llvmpipe: 2 -> 4): what it gave.
  GLint given = 0;
  glGetNamedRenderbufferParameteriv(t->color_, GL_RENDERBUFFER_SAMPLES, &given);
  t->samples_ = std::max(1, static_cast<int>(given));
  glCreateRenderbuffers(1, &t->depth_);
  glNamedRenderbufferStorageMultisample(t->depth_, ms, GL_DEPTH_COMPONENT24, width, height);
  if (ms) {
    glCreateRenderbuffers(1, &t->resolve_color_);
    glNamedRenderbufferStorage(t->resolve_color_, GL_RGBA8, width, height);
    glCreateFramebuffers(1, &t->resolve_fbo_);
    glNamedFramebufferRenderbuffer(t->resolve_fbo_, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, t->resolve_color_);
  }
  glCreateFramebuffers(1, &t->fbo_);
  glNamedFramebufferRenderbuffer(t->fbo_, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, t->color_);
  glNamedFramebufferRenderbuffer(t->fbo_, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, t->depth_);
  if (glCheckNamedFramebufferStatus(t->fbo_, GL_DRAW_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    return Error{"", "target", "framebuffer incomplete"};
  return t;
}

OffscreenTarget::~OffscreenTarget() {
  glDeleteFramebuffers(1, &fbo_);
  glDeleteRenderbuffers(1, &color_);
  glDeleteRenderbuffers(1, &depth_);
  if (resolve_fbo_) {
    glDeleteFramebuffers(1, &resolve_fbo_);
    glDeleteRenderbuffers(1, &resolve_color_);
  }
}

void OffscreenTarget::bind(bool clear) {
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
  glViewport(0, 0, width_, height_);
  if (clear) {
    glClearColor(0, 0, 0, 0);
    glClearDepth(1.0);
    glDepthMask(GL_TRUE);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  }
}

std::vector<std::uint8_t> OffscreenTarget::read_rgba() const {
  std::vector<std::uint8_t> px(static_cast<std::size_t>(width_) * height_ * 4);
  if (resolve_fbo_) {
    glBlitNamedFramebuffer(fbo_, resolve_fbo_, 0, 0, width_, height_, 0, 0, width_, height_, GL_COLOR_BUFFER_BIT, GL_NEAREST);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, resolve_fbo_);
  } else {
    glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo_);
  }
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, width_, height_, GL_RGBA, GL_UNSIGNED_BYTE, px.data());
  const std::size_t row = static_cast<std::size_t>(width_) * 4;
  std::vector<std::uint8_t> tmp(row);
  for (int y = 0; y < height_ / 2; ++y) {
    std::uint8_t* a = px.data() + y * row;
    std::uint8_t* b = px.data() + (height_ - 1 - y) * row;
    std::memcpy(tmp.data(), a, row);
    std::memcpy(a, b, row);
    std::memcpy(b, tmp.data(), row);
  }
  return px;
}

GpuTimer::GpuTimer() { glCreateQueries(GL_TIME_ELAPSED, 1, &query_); }
GpuTimer::~GpuTimer() { glDeleteQueries(1, &query_); }
void GpuTimer::begin() { glBeginQuery(GL_TIME_ELAPSED, query_); }
void GpuTimer::end() { glEndQuery(GL_TIME_ELAPSED); }
double GpuTimer::elapsed_ms() {
  GLuint64 ns = 0;
  glGetQueryObjectui64v(query_, GL_QUERY_RESULT, &ns);
  return static_cast<double>(ns) * 1e-6;
}

void gpu_finish() { glFinish(); }

}  // namespace bb::runtime
