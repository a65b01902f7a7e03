#include "sky_lib.glsl"
#include "octahedral_lib.glsl"
#include "radiance_cache_layout_lib.glsl"
/* Lumen GI: reading the world radiance cache (needs radiance_cache_layout_lib.glsl,
 * octahedral_lib.glsl, sky_lib.glsl and the samplers rc_cells, rc_slots, rc_state, rc_atlas,
 * rc_miss).
 *
 * rc_lookup(o, d, k): the far-field radiance for a screen-probe ray from o along d that met
 * nothing within rc_trace_distance(k): the 8 probes around o, trilinear weights, each read in
 * the lecture's sphere-parallax direction: the ray's exit point X from the probe's sphere of
 * radius RC_RADIUS spacings (o is inside every such sphere, so X exists and lies within the
 * distance the screen ray covered), direction X - P. Leak rule: the probe's own rays in that
 * texel (from P, full length) must not have met a surface before X (the atlas' alpha, the
 * texel's nearest hit): else a wall lies between the probe and the ray, and the probe (in a
 * solid, behind a thin wall) is left out. A texel holds its hits' light plus the share of its
 * rays that left the scene: that share of the sky is read in the ray's own direction d. False when no probe is left (the ray traces on).
 * rc_radiance (radiance_cache_trace_lib.glsl): a whole ray, short trace + cache.
 */
#ifndef LUMEN_RC_LIB
#define LUMEN_RC_LIB

bool rc_lookup(vec3 o, vec3 d, int k, out vec3 L)
{
  L = vec3(0.0);
  if (k < 0) {
    return false;
  }
  float s = rc_spacing(k);
  float R = RC_RADIUS * s;
  vec3 g = o / s - 0.5;
  ivec3 i0 = ivec3(floor(g));
  vec3 f = g - vec3(i0);
  vec3 sum = vec3(0.0);
  float wsum = 0.0;
  for (int c = 0; c < 8; c++) {
    ivec3 off = ivec3(c & 1, (c >> 1) & 1, c >> 2);
    vec3 wv = mix(1.0 - f, f, vec3(off));
    float w = max(wv.x * wv.y * wv.z, 1e-4);   /* a probe at a corner still counts a little */
    ivec3 cell = i0 + off;
    int slot = int(texelFetch(rc_cells, rc_cell_texel(k, cell), 0).x + 0.5) - 1;
    if (slot < 0) {
      continue;
    }
    ivec2 st = rc_slot_texel(slot);
    vec4 sv = texelFetch(rc_slots, st, 0);
    if (int(sv.w + 0.5) != k + 1 || any(notEqual(ivec3(floor(sv.xyz + 0.5)), cell))
        || texelFetch(rc_state, st, 0).x < 0.5) {
      continue;                                 /* not this cell's probe, or not traced yet */
    }
    vec3 op = o - rc_probe_pos(k, cell);
    float b = dot(d, op);
    float cc = dot(op, op) - R * R;
    float tx = -b + sqrt(max(b * b - cc, 0.0));
    vec4 r = texelFetch(rc_atlas, st * RC_RES + oct_texel(op + tx * d, RC_RES), 0);
    if (r.a < R) {
      continue;                                 /* the probe cannot see X */
    }
    sum += w * (r.rgb + texelFetch(rc_miss, st * RC_RES + oct_texel(op + tx * d, RC_RES), 0).x
                * sky_ray(d));
    wsum += w;
  }
  if (wsum <= 0.0) {
    return false;
  }
  L = sum / wsum;
  return true;
}
#endif /* LUMEN_RC_LIB */
