#include "sdf_lib.glsl"
#include "global_sdf_lib.glsl"
#include "gi_trace_lib.glsl"
#define SCREEN_BOUNDS             /* screen_trace_lib.glsl: the walk reads screen_bounds */
#include "screen_trace_lib.glsl"
/* Lumen's ray (lecture 21, "Speed of Different Tracing Methods"; needs gi_trace_lib.glsl,
 * screen_trace_lib.glsl and screen_trace.py's SAMPLERS and PUSH): the screen first (HZB, at
 * most screen_steps cells), then from where the depth buffer stops vouching for the ray (t_free)
 * the mesh SDFs, the global SDF and the sky (gi_radiance_from). A screen hit's light
 * (screen_camera texel 4 y, screen_trace.HITS): "CACHE" the surface cache where the SDF trace
 * from t_free places the hit (lumen_screen_free; one pass, screen_probe_lumen_trace), "COLOUR"
 * the screen colour at the screen's hit (lumen_screen_walk, lumen_screen_hit; three passes over
 * compacted lists, screen_probe_screen_trace.comp.glsl). lumen_radiance runs one ray either way
 * (the TRACE_METHOD debug view).
 * screen_steps 0: the SDFs from the origin.
 * Objects hidden from the camera (screen_hidden: their object-table rows, -1 for none) are not in
 * the depth buffer, which therefore vouches for space they fill: before a screen result is used,
 * the ray is sphere-traced against them alone up to where the screen trace ended; if it comes
 * within a voxel of one, the SDF trace takes over from just before (it sees every object).
 * kind: LUMEN_SKY (nothing hit before tmax), LUMEN_SCREEN (found by the screen), LUMEN_MESH
 * (a hit before GSDF_MESH_SPLIT), LUMEN_GLOBAL (after it). */
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

/* The walk (at most screen_steps HZB cells; free_only: it ends where it stops vouching, for
 * lumen_screen_free) and how far the depth buffer vouches for o + t dir (t_free), minus
 * LUMEN_FREE_BACKOFF voxels. Why the back-off: the depth buffer shows no surface the camera does
 * not see (a porch roof's underside, a wall's outer face), and the walk's own margin keeps a
 * voxel only from the surfaces it shows, so the last pixels it vouches for may end at such a
 * surface or just past it, where the SDF trace would start beyond it. Measured
 * (bench/quality.py, 128 px, every ray's hit placed by the SDFs): without it yard read the sky
 * through its porch roof (+1.4% relMSE over the SDF-only trace, one 8x8 block under the roof's
 * edge) and window +1.3%; one voxel: -0.2% and +0.8%; two voxels: yard +1.3% again (a start
 * farther back takes other steps along a grazing ray). */
#define LUMEN_FREE_BACKOFF 1.0

float lumen_walk(vec3 o, vec3 dir, float tmax, bool free_only, out float t_free, out ivec2 hit_px)
{
  /* A ray that starts inside a surface's hit shell (a probe in a concave corner) hits it at
   * once on the SDFs (sdf_ray_lib.glsl), and must here too: the walk, which leaves its start
   * pixel untested, vouched for the pixels around the corner, and the SDF trace started past
   * the shell (bench/quality.py's `glow`: half the rays that differed from the SDF-only
   * trace, found the far side of the room; tests/gpu/test_screen_trace_corners.py). Tested
   * before the walk, which such a ray does not need. */
  float h;
  int nearest;
  float d = sdf_scene(o, h, nearest);
  if (d <= GI_HIT_VOXELS * h) {
    t_free = 0.0;
    hit_px = ivec2(-1);
    return SCREEN_BEHIND;
  }
  float ts = screen_trace(screen_view_proj(), screen_cam.xyz, o, dir, tmax, screen_steps,
                          screen_cam.w, 2.0 * gi_thin_margin(), true, free_only, t_free, hit_px);
  float end = ts >= 0.0 ? ts : t_free;
  float guard = screen_hidden_guard(o, dir, end);
  if (guard < end) {               /* a hidden object first: the SDFs from there */
    t_free = min(t_free, guard);
    ts = SCREEN_BEHIND;
    hit_px = ivec2(-1);
  }
  /* The SDF trace from the origin would take this sample first and step to max(d, 0.1 h)
   * (gi_trace_mesh), or past the mesh SDFs' reach: it starts there at least, a sample
   * fewer for the rays the screen vouches for less (a quarter to two fifths of them). */
  t_free = max(t_free - LUMEN_FREE_BACKOFF * 2.0 * gi_thin_margin(),
               min(max(d, 0.1 * h), GSDF_MESH_SPLIT));
  return ts;
}

/* Lumen's ray with HITS "CACHE" (the default): the screen walk vouches for the ray's empty part
 * (t_free), and the mesh SDFs, global SDF and sky go on from there: a screen hit is found by the
 * SDF trace's last steps and read where an SDF hit reads it (the surface cache at the SDF's
 * shell), so the screen changes where the trace starts and not what it reads. Reading the cache
 * at the screen's own hit (the depth buffer's plane) was darker where the SDF's half-voxel shell
 * finds what the screen passes by (bench/quality.py: glow +2.0%, window +1.7%, textured +1.8%
 * relMSE over the SDF-only trace; the README's issue 12 notes). */
float lumen_screen_free(vec3 o, vec3 dir, float tmax, out ivec2 near_px)
{
  float t_free;
  lumen_walk(o, dir, tmax, true, t_free, near_px);
  return t_free;
}

/* HITS "COLOUR" (the lecture's): the walk, true where the screen finds a hit (distance ts, on
 * pixel hit_px's surface) that no camera-hidden object comes before; else false, and t_free is
 * where the SDF trace goes on (0 where the screen vouches for nothing). Its light is
 * lumen_screen_hit's. Two functions because the screen probes run them as two passes, each over
 * a compacted list (screen_probe_screen_trace.comp.glsl). */
bool lumen_screen_walk(vec3 o, vec3 dir, float tmax, out float t_free, out float ts,
                       out ivec2 hit_px)
{
  ts = lumen_walk(o, dir, tmax, false, t_free, hit_px);
  return ts >= 0.0;
}

/* The light L of a screen hit (lumen_screen_walk's ts, hit_px) of the ray o + t dir with HITS
 * "COLOUR": the screen colour over the ray's cone (screen_cone). */
vec3 lumen_screen_hit(vec3 o, vec3 dir, float ts, ivec2 hit_px)
{
  vec4 cone = texelFetch(screen_camera, ivec2(4, 0), 0);
  return screen_cone(screen_colour, screen_view_proj(), screen_cam.xyz, cone.x, o + dir * ts, ts,
                     hit_px);
}

/* One ray as the screen probes trace it (the TRACE_METHOD debug view). kind LUMEN_SCREEN: with
 * HITS "COLOUR" a screen hit; with "CACHE" a hit on the surface where the walk ended (the SDF's
 * hit within a voxel of the plane of the pixel the ray came near): the screen found the surface,
 * the SDF's last steps placed the hit. */
vec3 lumen_radiance(vec3 o, vec3 dir, float tmax, out float hit_t, out int kind)
{
  float t_free = 0.0;
  bool cache_hits = texelFetch(screen_camera, ivec2(4, 0), 0).y > 0.5;
  ivec2 near_px = ivec2(-1);
  if (screen_steps > 0 && cache_hits) {
    t_free = lumen_screen_free(o, dir, tmax, near_px);
  }
  else if (screen_steps > 0) {
    float ts;
    ivec2 hit_px;
    if (lumen_screen_walk(o, dir, tmax, t_free, ts, hit_px)) {
      hit_t = ts;
      kind = LUMEN_SCREEN;
      return lumen_screen_hit(o, dir, ts, hit_px);
    }
  }
  float w;
  vec3 L = gi_radiance_from(o, dir, t_free, tmax, hit_t, w);
  kind = hit_t >= tmax ? LUMEN_SKY : (hit_t < GSDF_MESH_SPLIT ? LUMEN_MESH : LUMEN_GLOBAL);
  vec3 ps, ns;
  if (kind != LUMEN_SKY && near_px.x >= 0 && gbuf_surface(near_px, screen_cam.xyz, ps, ns)
      && abs(dot(o + dir * hit_t - ps, ns)) <= 2.0 * gi_thin_margin()) {
    kind = LUMEN_SCREEN;
  }
  return L;
}
