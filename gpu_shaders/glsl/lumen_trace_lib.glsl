#include "sdf_lib.glsl"
#include "global_sdf_lib.glsl"
#include "gi_trace_lib.glsl"
#include "screen_trace_lib.glsl"
/* Lumen's ray (lecture 21, "Speed of Different Tracing Methods"; needs gi_trace_lib.glsl,
 * screen_trace_lib.glsl and screen_trace.py's SAMPLERS and PUSH): the screen first (HZB, at
 * most screen_steps cells; a hit reads screen_colour, filtered over the ray's cone:
 * screen_cone), then from where the depth buffer stops vouching for the ray (t_free) the mesh
 * SDFs, the global SDF and the sky (gi_radiance_from).
 * screen_steps 0: the SDFs from the origin.
 * Objects hidden from the camera (screen_hidden: their object-table rows, -1 for none) are not in
 * the depth buffer, which therefore vouches for space they fill: before a screen result is used,
 * the ray is sphere-traced against them alone up to where the screen trace ended; if it comes
 * within a voxel of one, the SDF trace takes over from just before (it sees every object).
 * kind: LUMEN_SKY (nothing hit before tmax), LUMEN_SCREEN, LUMEN_MESH (a hit before
 * GSDF_MESH_SPLIT), LUMEN_GLOBAL (after it). */
#define LUMEN_SKY 0
#define LUMEN_SCREEN 1
#define LUMEN_MESH 2
#define LUMEN_GLOBAL 3

mat4 screen_view_proj()
{
  return mat4(texelFetch(screen_camera, ivec2(0, 0), 0), texelFetch(screen_camera, ivec2(1, 0), 0),
              texelFetch(screen_camera, ivec2(2, 0), 0), texelFetch(screen_camera, ivec2(3, 0), 0));
}

/* The distance along o + t dir (t < t_end) at which the ray comes within a voxel of a
 * camera-hidden object, minus that voxel (where a full trace must start to find it); t_end when
 * it does not. Sphere tracing over those objects alone: few, and their steps are long. */
float screen_hidden_guard(vec3 o, vec3 dir, float t_end)
{
  int n = textureSize(screen_hidden, 0).x;
  if (texelFetch(screen_hidden, ivec2(0, 0), 0).x < 0.0) {
    return t_end;
  }
  float t = 0.0;
  for (int s = 0; s < 96 && t < t_end; s++) {
    vec3 p = o + dir * t;
    float best = 1e30, voxel = 1.0;
    int nearest = -1;
    for (int k = 0; k < n; k++) {
      sdf_visit(int(texelFetch(screen_hidden, ivec2(k, 0), 0).x + 0.5), p, best, voxel, nearest);
    }
    if (best < voxel) {
      return max(t - voxel, 0.0);
    }
    t += best - 0.5 * voxel;
  }
  return t_end;
}

vec3 lumen_radiance(vec3 o, vec3 dir, float tmax, out float hit_t, out int kind)
{
  float t_start = 0.0;
  bool on_screen = false;
  if (screen_steps > 0) {
    float t_free;
    ivec2 hit_px;
    float ts = screen_trace(screen_view_proj(), screen_cam.xyz, o, dir, tmax, screen_steps,
                            screen_cam.w, 2.0 * gi_thin_margin(), true, t_free, hit_px);
    float guard = screen_hidden_guard(o, dir, ts >= 0.0 ? ts : t_free);
    if (guard < (ts >= 0.0 ? ts : t_free)) {     /* a hidden object first: the SDFs from there */
      ts = -1.0;
      t_free = min(t_free, guard);
    }
    vec4 cone = texelFetch(screen_camera, ivec2(4, 0), 0);
    if (ts >= 0.0 && cone.y < 0.5) {
      hit_t = ts;
      kind = LUMEN_SCREEN;
      return screen_cone(screen_colour, screen_view_proj(), screen_cam.xyz, cone.x,
                         o + dir * ts, ts, hit_px);
    }
    /* SCREEN_HIT_CACHE (cone.y 1): a hit's light is the surface cache's, as an SDF hit reads
     * it: the SDFs go on from the hit pixel's entry (t_free), a step or two from the surface */
    on_screen = ts >= 0.0;
    t_start = t_free;
  }
  float w;
  vec3 L = gi_radiance_from(o, dir, t_start, tmax, hit_t, w);
  kind = on_screen ? LUMEN_SCREEN :
         (hit_t >= tmax ? LUMEN_SKY : (hit_t < GSDF_MESH_SPLIT ? LUMEN_MESH : LUMEN_GLOBAL));
  return L;
}
