#include "gbuffer_lib.glsl"
#include "mip_lib.glsl"
/* Screen-space rays on the HZB (lecture 21, "Hierachical Tracing"; needs mip_lib.glsl,
 * gbuffer_lib.glsl and the samplers hzb (MIN chain of window depths, hzb.py), gbuf_position,
 * gbuf_normal; with SCREEN_BOUNDS defined, screen_bounds). Used by SSGI's trace and by Lumen's
 * first trace (screen probes).
 *
 * screen_trace walks o + t dir (t in [0, t_max]) as a straight line in (pixel x, pixel y, window
 * depth):
 *   a segment whose depth stays in front of its cell's MIN skips the cell and climbs a level;
 *   otherwise it descends; at level 0 the segment inside the pixel is tested against the
 *   pixel's surface plane (G-buffer position and normal): it hits where it crosses the plane
 *   from in front, or if it entered the pixel behind the plane by at most `thickness` metres
 *   moving against the surface's normal (surfaces are assumed that thick: the depth buffer has
 *   no back faces; a ray moving with the normal is leaving from behind a thin wall and would
 *   meet its unseen back); otherwise it walks on behind the surface. (The plane and not the
 *   pixel's centre depth: at a grazing angle one pixel spans a long stretch of its surface.)
 * At most max_steps cells are visited (the lecture: 50). The world ray is clipped to the near and
 * far planes, its screen line to the image.
 * free_only (Lumen's first trace with its hits placed by the mesh SDFs, lumen_trace_lib.glsl:
 * lumen_screen_free): only t_free is wanted, so the walk ends at the first pixel that does not
 * vouch for the ray (SCREEN_BEHIND, hit_px that pixel), instead of walking on to a hit it would
 * not use.
 * stop_behind (Lumen's first trace, which has a world trace to go on with): a ray that passes
 * behind a pixel's surface without hitting it ends there (SCREEN_BEHIND) instead of walking on
 * behind it: what lies behind is unknown to the screen (the walk found surfaces beyond a thin
 * wall's edge: `thin` leaked 1.98% against the SDFs' 0.21%), and the walk behind an occluder,
 * one pixel per step, spent the step budget for a result the SDFs then recomputed. SSGI, which
 * has no world trace, walks on (stop_behind false).
 * Returns the hit distance (>= 0; hit_px the pixel hit) or SCREEN_LEFT (left the screen, reached
 * t_max or the far plane) or SCREEN_STEPS (out of steps) or SCREEN_BEHIND.
 * t_free: how far the ray is known to be empty, from the depth buffer alone: every cell it crossed
 * from its start up to there it crossed in front of the nearest surface the cell shows (what the
 * camera sees in front of a surface is empty). A world-space tracer can go on from there without
 * missing anything (Lumen's screen trace then mesh SDF trace).
 */
#define SCREEN_LEFT -1.0
#define SCREEN_STEPS -2.0
#define SCREEN_BEHIND -3.0
/* window depth: the neighbours' bound is taken this much nearer (float rounding) */
#define SCREEN_BOUND_EPS 1e-6

/* The window depth in front of which pixel px's column is in front of its 4 neighbours' planes
 * (screen_bounds.comp.glsl; Lumen's trace defines SCREEN_BOUNDS and binds screen_bounds); 2.0,
 * no bound, for SSGI, which does not ask (stop_behind false). */
float screen_bound(ivec2 px)
{
#ifdef SCREEN_BOUNDS
  return texelFetch(screen_bounds, px, 0).x;
#else
  return 2.0;
#endif
}

vec3 screen_window(vec4 h, vec2 size)
{
  vec3 ndc = h.xyz / h.w;
  return vec3((ndc.xy * 0.5 + 0.5) * size, ndc.z * 0.5 + 0.5);
}

float screen_trace(mat4 view_proj, vec3 cam_pos, vec3 o, vec3 dir, float t_max, int max_steps,
                   float thickness, float free_margin, bool stop_behind, bool free_only,
                   out float t_free, out ivec2 hit_px)
{
  t_free = 0.0;
  hit_px = ivec2(-1);
  ivec2 size = textureSize(gbuf_position, 0);
  vec4 h0 = view_proj * vec4(o, 1.0);
  vec4 h1 = view_proj * vec4(o + dir * t_max, 1.0);
  /* clip the world segment to the near (z + w >= 0) and far (w - z >= 0) planes */
  float frac = 1.0;
  float a0 = h0.z + h0.w, a1 = h1.z + h1.w;
  if (a1 < 0.0) {
    frac = min(frac, 0.999 * a0 / (a0 - a1));
  }
  float b0 = h0.w - h0.z, b1 = h1.w - h1.z;
  if (b1 < 0.0) {
    frac = min(frac, 0.999 * b0 / (b0 - b1));
  }
  float len = t_max * frac;
  h1 = mix(h0, h1, frac);
  vec3 s0 = screen_window(h0, vec2(size));
  vec3 s1 = screen_window(h1, vec2(size));
  vec3 d = s1 - s0;
  float w0 = h0.w, w1 = h1.w;

  /* where the screen line leaves the image */
  float s_end = 1.0;
  if (d.x > 0.0) {
    s_end = min(s_end, (float(size.x) - s0.x) / d.x);
  }
  else if (d.x < 0.0) {
    s_end = min(s_end, -s0.x / d.x);
  }
  if (d.y > 0.0) {
    s_end = min(s_end, (float(size.y) - s0.y) / d.y);
  }
  else if (d.y < 0.0) {
    s_end = min(s_end, -s0.y / d.y);
  }
  float pix_len = length(d.xy);
  float eps = 1e-3 / max(pix_len, 1e-6);
  vec2 inv_d = vec2(d.x != 0.0 ? 1.0 / d.x : 1e30, d.y != 0.0 ? 1.0 / d.y : 1e30);

  int top = mip_count(size) - 1;
  int level = 0;
  float s = 0.0;
  bool first = true;        /* the start pixel: leave it before testing anything */
  bool free_so_far = true;  /* every cell crossed so far was crossed in front of its surface */
  for (int i = 0; i < max_steps; i++) {
    if (s >= s_end) {
      break;
    }
    vec3 P = s0 + d * s;
    ivec2 cell = ivec2(floor(clamp(P.xy, vec2(0.0), vec2(size) - 1e-3))) >> level;
    float cs = float(1 << level);
    vec2 lo = vec2(cell) * cs;
    vec2 hi = lo + cs;
    float sx = d.x > 0.0 ? (hi.x - s0.x) * inv_d.x : (d.x < 0.0 ? (lo.x - s0.x) * inv_d.x : 1e30);
    float sy = d.y > 0.0 ? (hi.y - s0.y) * inv_d.y : (d.y < 0.0 ? (lo.y - s0.y) * inv_d.y : 1e30);
    float s_exit = min(min(sx, sy), s_end);
    float tb = len * (s_exit * w0 / ((1.0 - s_exit) * w1 + s_exit * w0));
    if (first) {
      first = false;
      s = s_exit + eps;
      continue;
    }
    float za = s0.z + d.z * s;
    float zb = s0.z + d.z * s_exit;
    ivec2 off, lsize;
    mip_rect(level, size, off, lsize);
    float zmin = texelFetch(hzb, off + cell, 0).x;
    if (max(za, zb) < zmin) {
      s = s_exit + eps;
      level = min(level + 1, top);
      if (free_so_far) {
        t_free = tb;
      }
      continue;
    }
    if (level > 0) {
      level--;
      continue;
    }
    /* level 0: the pixel's surface plane, distances positive on the camera's side */
    vec3 ps, ns;
    if (gbuf_surface(cell, cam_pos, ps, ns)) {
      float ta = len * (s * w0 / ((1.0 - s) * w1 + s * w0));
      float da = dot(o + dir * ta - ps, ns);
      float db = dot(o + dir * tb - ps, ns);
      if (da >= 0.0 && db < 0.0) {          /* crosses the plane from in front */
        hit_px = cell;
        return ta + (tb - ta) * da / (da - db);
      }
      if (da < 0.0 && da >= -thickness && dot(dir, ns) < 0.0) {
        /* entered the pixel behind it, within the thickness, going the way the surface faces
         * away from: a hit on it. Going the other way the ray is behind a wall on its way out
         * (a thin wall seen from outside, the ray from inside): what it meets is the wall's
         * back, which the screen does not show (the sunlit outside was read there: leak) */
        hit_px = cell;
        return ta;
      }
      if (stop_behind && (da < 0.0 || db < 0.0)) {
        /* behind what the pixel shows and no hit: the screen cannot tell what the ray meets
         * there (an occluder's hidden part, a thin wall's back): a world trace goes on from
         * t_free rather than the walk finding a surface farther on that may lie beyond it */
        return SCREEN_BEHIND;
      }
      /* Empty in front of what the pixel shows only from free_margin on (Lumen: a voxel): the
       * depth buffer does not show what lies within a voxel of a surface (a panel 5 cm under a
       * ceiling, seen edge-on from the ceiling beside it: bench/quality.py glow's ceiling lost
       * its halo, relMSE 0.0209 -> 0.0240). Nor the sub-pixel rim of a neighbour's surface
       * (a 10 cm wall's side at 48 px was passed through: its floor lost 4.7% of the wall's
       * light, test_screen_trace): with a world trace to go on from t_free (stop_behind), the
       * segment must also lie in front of the neighbours' bound (screen_bound: in front of
       * each of its four neighbours' planes that is not its own). Why a bound made once per
       * pixel (screen_bounds.comp.glsl) and not the four planes tested here: those
       * tests (eight G-buffer fetches in a loop) made the probe trace 5-16% slower even where
       * no ray ran them (llvmpipe; bench/f12_ab.py, the README's issue 12 notes). It is
       * stricter: a ray passing far behind a neighbour's plane (behind a nearer object's
       * silhouette) is no longer vouched for there, and the SDFs go on from that point. */
      bool front = da >= free_margin && db >= free_margin
                   && (!stop_behind || max(za, zb) < screen_bound(cell) - SCREEN_BOUND_EPS);
      free_so_far = free_so_far && front;
      if (free_only && !free_so_far) {
        hit_px = cell;                    /* the surface the ray came near */
        return SCREEN_BEHIND;             /* t_free is final: the rest of the walk is not needed */
      }
    }
    if (free_so_far) {
      t_free = tb;
    }
    s = s_exit + eps;
  }
  return s >= s_end ? SCREEN_LEFT : SCREEN_STEPS;
}

/* The colour (a lit image: Lumen's screen colour) a hit at y (distance t, on pixel px's surface)
 * reads: the mean over the ray's footprint, edge-aware. The cone of half-angle atan(cone_tan)
 * the ray stands for (Lumen: a probe texel's solid angle) is projected at y (camera at cam);
 * 3x3 taps spaced over its radius (1 to SCREEN_CONE_MAX_PX pixels apart) are averaged where
 * the tap's surface is y's (its plane passes within 2 cm + 10% of the tap's distance of y,
 * its normal within ~45 degrees).
 * Why: one pixel of the screen colour carries the noise of one gather's per-pixel light (F12:
 * the last gather's), and a ray stands for its cone's mean, which the SDF path's surface cache
 * (texels a few cm across, read at jittered directions) gives with less noise. Edge-aware and
 * not the mip chain's cone filter: a mip texel averages whatever the screen shows around y
 * (a black floor under an emitting wall read the wall 8% darker, test_screen_trace). */
#define SCREEN_CONE_MAX_PX 4.0
vec3 screen_cone(sampler2D colour, mat4 vp, vec3 cam, float cone_tan, vec3 y, float t, ivec2 px)
{
  ivec2 size = textureSize(gbuf_position, 0);
  vec3 view = normalize(y - cam);
  vec3 across = normalize(cross(view, abs(view.z) < 0.9 ? vec3(0.0, 0.0, 1.0) :
                                                          vec3(1.0, 0.0, 0.0)));
  vec3 c = screen_window(vp * vec4(y, 1.0), vec2(size));
  vec3 c2 = screen_window(vp * vec4(y + across * (t * cone_tan), 1.0), vec2(size));
  float spacing = min(length(c2.xy - c.xy), SCREEN_CONE_MAX_PX);
  vec3 sum = texelFetch(colour, px, 0).rgb;
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
      sum += texelFetch(colour, q, 0).rgb;
      wsum += 1.0;
    }
  }
  return sum / wsum;
}
