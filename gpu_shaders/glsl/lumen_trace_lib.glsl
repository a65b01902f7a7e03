/* Lumen's ray (lecture 21, "Speed of Different Tracing Methods"; needs gi_trace_lib.glsl,
 * screen_trace_lib.glsl and screen_trace.py's SAMPLERS and PUSH): the screen first (HZB, at
 * most screen_steps cells; a hit reads screen_colour, filtered over the ray's cone), then from where the depth buffer stops
 * vouching for the ray (t_free) the mesh SDFs, the global SDF and the sky (gi_radiance_from).
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

/* The screen colour a hit at y (distance t, on pixel px's surface) reads: the mean over the ray's
 * footprint, edge-aware. The cone of half-angle atan(screen_camera texel 4 .x) the ray stands
 * for (a probe texel's solid angle) is projected at y; 3x3 taps spaced over its radius (1 to
 * SCREEN_CONE_MAX_PX pixels apart) are averaged where the tap's surface is y's (its plane passes
 * within 2 cm + 10% of the tap's distance of y, its normal within ~45 degrees).
 * Why: one pixel of the screen colour carries the noise of one gather's per-pixel light (F12:
 * the last gather's), and a ray stands for its cone's mean, which the SDF path's surface cache
 * (texels a few cm across, read at jittered directions) gives with less noise. Edge-aware and
 * not the mip chain's cone filter: a mip texel averages whatever the screen shows around y
 * (a black floor under an emitting wall read the wall 8% darker, test_screen_trace). */
#define SCREEN_CONE_MAX_PX 4.0
vec3 screen_cone(vec3 y, float t, ivec2 px)
{
  ivec2 size = textureSize(gbuf_position, 0);
  mat4 vp = screen_view_proj();
  float cone_tan = texelFetch(screen_camera, ivec2(4, 0), 0).x;
  vec3 view = normalize(y - screen_cam.xyz);
  vec3 across = normalize(cross(view, abs(view.z) < 0.9 ? vec3(0.0, 0.0, 1.0) :
                                                          vec3(1.0, 0.0, 0.0)));
  vec3 c = screen_window(vp * vec4(y, 1.0), vec2(size));
  vec3 c2 = screen_window(vp * vec4(y + across * (t * cone_tan), 1.0), vec2(size));
  float spacing = min(length(c2.xy - c.xy), SCREEN_CONE_MAX_PX);
  vec3 sum = texelFetch(screen_colour, px, 0).rgb;
  if (spacing < 1.0) {
    return sum;                   /* the cone within a pixel */
  }
  vec3 n0 = texelFetch(gbuf_normal, px, 0).xyz;
  float wsum = 1.0;
  for (int j = -1; j <= 1; j++) {
    for (int i = -1; i <= 1; i++) {
      if (i == 0 && j == 0) {
        continue;
      }
      ivec2 q = ivec2(floor(vec2(px) + 0.5 + vec2(i, j) * spacing));
      if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, size))) {
        continue;
      }
      vec4 pq = texelFetch(gbuf_position, q, 0);
      vec3 nq = texelFetch(gbuf_normal, q, 0).xyz;
      if (pq.w < 0.5 || abs(dot(nq, n0)) < 0.7) {
        continue;
      }
      vec3 d = pq.xyz - y;
      if (abs(dot(d, normalize(nq))) > 0.02 + 0.1 * length(d)) {
        continue;
      }
      sum += texelFetch(screen_colour, q, 0).rgb;
      wsum += 1.0;
    }
  }
  return sum / wsum;
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
  if (screen_steps > 0) {
    float t_free;
    ivec2 hit_px;
    float ts = screen_trace(screen_view_proj(), screen_cam.xyz, o, dir, tmax, screen_steps,
                            screen_cam.w, true, t_free, hit_px);
    float guard = screen_hidden_guard(o, dir, ts >= 0.0 ? ts : t_free);
    if (guard < (ts >= 0.0 ? ts : t_free)) {     /* a hidden object first: the SDFs from there */
      ts = -1.0;
      t_free = min(t_free, guard);
    }
    if (ts >= 0.0) {
      hit_t = ts;
      kind = LUMEN_SCREEN;
      return screen_cone(o + dir * ts, ts, hit_px);
    }
    t_start = t_free;
  }
  float w;
  vec3 L = gi_radiance_from(o, dir, t_start, tmax, hit_t, w);
  kind = hit_t >= tmax ? LUMEN_SKY : (hit_t < GSDF_MESH_SPLIT ? LUMEN_MESH : LUMEN_GLOBAL);
  return L;
}
