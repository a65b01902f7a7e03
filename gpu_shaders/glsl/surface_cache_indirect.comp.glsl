#include "sdf_ray_lib.glsl"
#include "sh_lib.glsl"
#include "surface_cache_pages_lib.glsl"
#include "surface_cache_texel_lib.glsl"
#include "surface_cache_probe_lib.glsl"
/* Surface cache indirect light, step 3: per lighting-atlas texel, the irradiance of the 2x2 probes
 * around it (bilinear between probe centres, probes on the same card only; its own block's probe
 * when none), E = E0 + sh4_irradiance(c, n) - sh4_irradiance(c, n_probe): the probe's exact
 * irradiance, corrected by the SH for the texel's own normal; a probe that a wall hides from the
 * texel (gi_visible) is left out, and with no probe left the texel keeps its last value; then the
 * temporal blend
 * E = mix(E_prev, E_new, blend) (blend > 1: over-relaxed where safe, see the end). Multi-bounce: the probes read last frame's final light.
 * Runs over this frame's tiles (sc_pages: each with its own blend), in place: out_image holds
 * the previous E and is read and written by the same thread.
 * Inputs: texel_card, card tables and layers, sc_probes, sc_probe_sh, sc_probe_irradiance,
 * sc_probe_pos, sc_probe_room (the field at each probe's lifted end), sc_pages.
 * delta_image (read-write): each texel's last update E_new - E_prev, w = 1 once written.
 * Output out_image (read-write): E.rgb (irradiance, W/m^2), w = 1 on surface texels interpolated from probes,
 * 0.5 where no probe could be used (covered texels, e.g. a floor under a wall), 0 elsewhere.
 */
void main()
{
  ivec2 gid = ivec2(gl_GlobalInvocationID.xy);
  int page = gid.x / SCP_PAGE_TEXELS;
  ivec2 px = scp_page_texel(gid);
  ivec2 size = imageSize(out_image);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  int row, obj;
  vec3 p, n, albedo, emissive;
  if (!sc_lighting_texel(px, row, obj, p, n, albedo, emissive)) {
    imageStore(out_image, px, vec4(0.0));
    return;
  }
  ivec2 grid = textureSize(sc_probes, 0);
  vec2 g = (vec2(px) + 0.5) / float(SCP_SIZE) - 0.5;
  ivec2 i0 = ivec2(floor(g));
  vec2 f = g - vec2(i0);
  vec3 E = vec3(0.0);
  float wsum = 0.0;
  /* the texel's end of every probe's visibility test, sampled once (gi_visible_from): the
   * probes of its card are on its object and have its voxel */
  float lift_voxel = gi_object_voxel(obj);
  vec3 lifted = gi_lifted(p, n, lift_voxel);
  float h;
  int o;
  float room = sdf_scene(lifted, h, o);
  vec4 ga = vec4(0.0);            /* lifted's gradient, for the tests that need it */
  for (int k = 0; k < 4; k++) {
    ivec2 d = ivec2(k & 1, k >> 1);
    ivec2 q = clamp(i0 + d, ivec2(0), grid - 1);
    vec4 qi = texelFetch(sc_probes, q, 0);
    if (abs(qi.w - float(row + 1)) > 0.5) {
      continue;
    }
    vec4 qp = texelFetch(sc_probe_pos, q, 0);
    if (qp.w != lift_voxel) {  /* never so far: one card, one object */
      lift_voxel = qp.w;
      lifted = gi_lifted(p, n, qp.w);
      room = sdf_scene(lifted, h, o);
      ga = vec4(0.0);
    }
    if (!gi_visible_between(lifted, room, gi_lifted(qp.xyz, qi.xyz, qp.w),
                            texelFetch(sc_probe_room, q, 0).x, qp.w, ga)) {
      continue;
    }
    float w = (d.x == 1 ? f.x : 1.0 - f.x) * (d.y == 1 ? f.y : 1.0 - f.y) + 1e-3;
    vec3 c[4];
    for (int i = 0; i < 4; i++) {
      c[i] = texelFetch(sc_probe_sh, q * 2 + ivec2(i & 1, i >> 1), 0).rgb;
    }
    vec3 e0 = texelFetch(sc_probe_irradiance, q, 0).rgb;
    E += w * max(e0 + sh4_irradiance(c, n) - sh4_irradiance(c, qi.xyz), vec3(0.0));
    wsum += w;
  }
  vec3 prev = imageLoad(out_image, px).rgb;
  vec3 e = wsum > 0.0 ? E / wsum : prev;
  vec3 step = e - prev;
  float blend = scp_page_blend(page);
  /* blend > 1 (F12): over-relaxation, E + blend (E_new - E), which reaches the many-bounce light
   * in fewer iterations, but only where this update goes the way this texel's last one went: a
   * mode that flips sign between iterations (light ringing between two close facing surfaces)
   * would grow under it; those texels take the plain step. */
  vec4 last = imageLoad(delta_image, px);
  if (blend > 1.0 && !(last.w > 0.5 && dot(step, last.rgb) > 0.0)) {
    blend = 1.0;
  }
  imageStore(delta_image, px, vec4(step, 1.0));
  imageStore(out_image, px, vec4(max(prev + blend * step, vec3(0.0)), wsum > 0.0 ? 1.0 : 0.5));
}
