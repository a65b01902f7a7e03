#include "surface_cache_lib.glsl"
#include "octahedral_lib.glsl"
#include "gi_trace_lib.glsl"
#include "radiance_cache_layout_lib.glsl"
/* Radiance cache, tracing: per listed probe and octahedral texel, RC_SUB^2 stratified rays
 * (jittered in the texel by rc_jitter, a new offset every trace) from the probe's centre, full
 * length (t_max) through gi_trace_lib.glsl (mesh SDFs, global SDF, voxel lighting / surface
 * cache, sky on a miss). Atlas texel: rgb the mean radiance of the rays that hit (misses count
 * 0), a the nearest hit of any of its rays so far (the lookup's visibility test); rc_miss_io
 * the share of rays that left the scene (the lookup adds the sky in the screen ray's own
 * direction: the sky is at infinity, no parallax, and sharper than 8 x 8 texels). A new probe
 * replaces, a re-trace blends by rc_blend (a running mean in F12, exponential in the viewport).
 * Texel (0, 0) stamps rc_state_io.x = frame + 1 (traced). Samplers rc_list, rc_slots.
 */
#define RC_SUB 1

void main()
{
  ivec2 gid = ivec2(gl_GlobalInvocationID.xy);
  ivec2 entry = gid / RC_RES;
  ivec2 texel = gid - entry * RC_RES;
  if (entry.x >= textureSize(rc_list, 0).x || entry.y >= textureSize(rc_list, 0).y) {
    return;
  }
  vec4 e = texelFetch(rc_list, entry, 0);
  if (e.x < -0.5) {
    return;
  }
  int slot = int(e.x + 0.5);
  ivec2 st = rc_slot_texel(slot);
  vec4 sv = texelFetch(rc_slots, st, 0);
  int k = int(sv.w + 0.5) - 1;
  vec3 P = rc_probe_pos(k, ivec3(floor(sv.xyz + 0.5)));
  vec3 sum = vec3(0.0);
  float nearest = t_max;
  float missed = 0.0;
  for (int j = 0; j < RC_SUB * RC_SUB; j++) {
    vec2 u = fract((vec2(j % RC_SUB, j / RC_SUB) + rc_jitter) / float(RC_SUB));
    vec3 dir = oct_texel_dir(texel, RC_RES, u);
    float t;
    int obj;
    vec3 voxel_L;
    if (gi_trace_lit(P, dir, t_max, t, obj, voxel_L)) {
      float w;
      sum += obj < 0 ? voxel_L : sc_sample_world(obj, P + t * dir, dir, w);
      nearest = min(nearest, t);
    }
    else {
      missed += 1.0;
    }
  }
  vec3 L = sum / float(RC_SUB * RC_SUB);
  missed /= float(RC_SUB * RC_SUB);
  ivec2 at = st * RC_RES + texel;
  if (e.y < 0.5) {
    vec4 old = imageLoad(rc_atlas_io, at);
    L = mix(old.rgb, L, rc_blend);
    nearest = min(nearest, old.a);
    missed = mix(imageLoad(rc_miss_io, at).x, missed, rc_blend);
  }
  imageStore(rc_atlas_io, at, vec4(L, nearest));
  imageStore(rc_miss_io, at, vec4(missed));
  if (texel == ivec2(0)) {
    imageStore(rc_state_io, st, vec4(float(rc_frame + 1), 0.0, 0.0, 0.0));
  }
}
