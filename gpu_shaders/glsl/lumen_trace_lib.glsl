#include "sdf_lib.glsl"
#include "global_sdf_lib.glsl"
#include "gi_trace_lib.glsl"
#include "screen_trace_lib.glsl"
/* Lumen's ray (lecture 21, "Speed of Different Tracing Methods"; needs gi_trace_lib.glsl,
 * screen_trace_lib.glsl and screen_trace.py's SAMPLERS and PUSH): the screen first (HZB, at
 * most screen_steps cells; lumen_screen: a hit reads the surface cache or the screen colour),
 * then from where the depth buffer stops vouching for the ray (t_free) the mesh SDFs, the
 * global SDF and the sky (gi_radiance_from). The screen probes run the walk, the hits' light
 * and the SDF trace as three passes over compacted lists (screen_probe_screen_trace.comp.glsl);
 * lumen_radiance runs them for one ray (the TRACE_METHOD debug view).
 * screen_steps 0: the SDFs from the origin.
 * Objects hidden from the camera (screen_hidden: their object-table rows, -1 for none) are not in
 * the depth buffer, which therefore vouches for space they fill: before a screen result is used,
 * the ray is sphere-traced against them alone up to where the screen trace ended; if it comes
 * within a voxel of one, the SDF trace takes over from just before (it sees every object).
 * kind: LUMEN_SKY (nothing hit before tmax), LUMEN_SCREEN (resolved by the screen), LUMEN_MESH
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

/* The screen part of Lumen's ray, its walk: true where the screen finds a hit (distance ts, on
 * pixel hit_px's surface) that no camera-hidden object comes before; else false, and t_free is
 * where the SDF trace goes on (0 where the screen vouches for nothing). Its light is
 * lumen_screen_hit's. Two functions because the screen probes run them as two passes, each over
 * a compacted list (screen_probe_screen_trace.comp.glsl). */
bool lumen_screen_walk(vec3 o, vec3 dir, float tmax, out float t_free, out float ts,
                       out ivec2 hit_px)
{
  ts = screen_trace(screen_view_proj(), screen_cam.xyz, o, dir, tmax, screen_steps, screen_cam.w,
                    2.0 * gi_thin_margin(), true, t_free, hit_px);
  float guard = screen_hidden_guard(o, dir, ts >= 0.0 ? ts : t_free);
  if (guard < (ts >= 0.0 ? ts : t_free)) {     /* a hidden object first: the SDFs from there */
    t_free = min(t_free, guard);
    return false;
  }
  return ts >= 0.0;
}

/* The light L of a screen hit (lumen_screen_walk's ts, hit_px) of the ray o + t dir; false where
 * the screen cannot give it (the SDF trace then goes on from the walk's t_free).
 * screen_camera texel 4 y: 1 (HITS "CACHE") the surface cache's at the hit, as an SDF hit reads
 * it: at the hit pixel's surface plane lifted half a voxel of the nearest object towards the
 * ray's side (an SDF hit lies there; read on the plane, a wall thinner than a voxel would give
 * either side's light); beyond GSDF_MESH_SPLIT, where the SDF trace's hits read voxel lighting,
 * voxel lighting there too (the G-buffer normal choosing its faces), the surface cache where it
 * holds nothing; so does a hit on an object the bake gave no cards (Min Card Size). A hit on something the SDFs do not hold (no object within 2 voxels) is left to
 * the SDF trace. 0 (HITS "COLOUR") the screen colour over the ray's cone (screen_cone).
 * Why voxel lighting far: a surface-cache read (the mesh SDF's normal, every card's 2x2 texels,
 * each tested against walls between) costs more than a whole SDF ray that ends in voxel
 * lighting: read for every hit, the screen's hits cost more than the trace they replaced
 * (bench/f12_ab.py, cornell 128 px: 2.7 CPU s for 64% of the rays against 2.8 for all of them). */
bool lumen_screen_hit(vec3 o, vec3 dir, float ts, ivec2 hit_px, out vec3 L)
{
  L = vec3(0.0);
  vec4 cone = texelFetch(screen_camera, ivec2(4, 0), 0);
  if (cone.y < 0.5) {
    L = screen_cone(screen_colour, screen_view_proj(), screen_cam.xyz, cone.x, o + dir * ts, ts,
                    hit_px);
    return true;
  }
  vec3 ps, ns;
  gbuf_surface(hit_px, screen_cam.xyz, ps, ns);
  vec3 p = o + dir * ts;
  p -= ns * dot(p - ps, ns);                   /* onto the plane (a hit within the thickness) */
  float h;
  int obj;
  float d = sdf_scene(p, h, obj);
  if (obj < 0 || abs(d) > 2.0 * h) {
    return false;
  }
  vec3 q = p + ns * (GI_HIT_VOXELS * h);
  if (ts >= GSDF_MESH_SPLIT || sc_instance_range(obj).y == 0) {   /* far, or no cards */
    int level;
    float v;
    global_sdf_sample(q, level, v);
    if (level >= 0 && vl_sample(level, q, dir, ns, L)) {
      return true;
    }
  }
  float w;
  L = sc_sample_world(obj, q, dir, w);
  return true;
}

/* Both parts for one ray: true where the screen resolves it (hit distance hit_t, light L). */
bool lumen_screen(vec3 o, vec3 dir, float tmax, out float t_free, out float hit_t, out vec3 L)
{
  ivec2 hit_px;
  L = vec3(0.0);
  float ts;
  bool hit = lumen_screen_walk(o, dir, tmax, t_free, ts, hit_px)
             && lumen_screen_hit(o, dir, ts, hit_px, L);
  hit_t = hit ? ts : tmax;
  return hit;
}

vec3 lumen_radiance(vec3 o, vec3 dir, float tmax, out float hit_t, out int kind)
{
  float t_free = 0.0;
  if (screen_steps > 0) {
    vec3 L;
    if (lumen_screen(o, dir, tmax, t_free, hit_t, L)) {
      kind = LUMEN_SCREEN;
      return L;
    }
  }
  float w;
  vec3 L = gi_radiance_from(o, dir, t_free, tmax, hit_t, w);
  kind = hit_t >= tmax ? LUMEN_SKY : (hit_t < GSDF_MESH_SPLIT ? LUMEN_MESH : LUMEN_GLOBAL);
  return L;
}
