#include "octahedral_lib.glsl"
#include "sh_lib.glsl"
/* Screen probes to spherical harmonics (lecture: "Convert Probe Radiance to 3rd order SH"): per
 * probe, c_k = sum over its octahedral texels of L * Y_k(dir) * texel solid angle (exact solid
 * angles, octahedral_lib.glsl), dir the direction actually traced (ray_jitter). The probe's
 * solid-angle mean radiance is taken out first and added to c_0 exactly: 64 jittered directions
 * (one jitter per frame for every texel) are not a symmetric quadrature, and the constant part
 * of L leaked into bands 1-2 (a uniform sky furnace gave E = pi L within -16%..+14% per frame,
 * right only on average over the jitter sequence); now a constant L gives pi L exactly.
 * Only the hemisphere above the probe's surface is projected; below it the SH holds that
 * hemisphere's mean. The rays below it hit the probe's own surface a voxel away (on a lit floor,
 * the floor's light), and the 9 terms' ringing carried that light to normals turned from the
 * probe's: an unlit face beside a lit one got ~1% of it, speckled (every probe's culled texels,
 * 4 L - 3 prior, are below it), and a lone sunlit cube under a black sky got up to 17% of its
 * direct light as "indirect" (Cycles: 0; tests/gpu/test_screen_probe_sampling.py). For the
 * pixels the probe serves (normals near its own, screen_probe_integrate) nothing below their
 * horizon counts; a constant L still gives pi L exactly.
 * Inputs: probe_info, probe_normal, probe_filtered (radiance rgb); probe_res, ray_jitter.
 * Output out_image: coefficient k of probe (i, j) at texel (3 i + k % 3, 3 j + k / 3), rgb.
 */
void main()
{
  ivec2 pr = ivec2(gl_GlobalInvocationID.xy);
  ivec2 grid = textureSize(probe_info, 0);
  if (pr.x >= grid.x || pr.y >= grid.y) {
    return;
  }
  vec3 c[9];
  for (int k = 0; k < 9; k++) {
    c[k] = vec3(0.0);
  }
  if (texelFetch(probe_info, pr, 0).w > 0.0) {
    vec3 pn = normalize(texelFetch(probe_normal, pr, 0).xyz);
    vec3 mean = vec3(0.0);
    float total = 0.0;
    for (int y = 0; y < probe_res; y++) {
      for (int x = 0; x < probe_res; x++) {
        ivec2 texel = ivec2(x, y);
        if (dot(oct_texel_dir(texel, probe_res, ray_jitter), pn) <= 0.0) {
          continue;
        }
        float sa = oct_texel_solid_angle(texel, probe_res);
        mean += texelFetch(probe_filtered, pr * probe_res + texel, 0).rgb * sa;
        total += sa;
      }
    }
    mean /= max(total, 1e-6);
    float b[9];
    for (int y = 0; y < probe_res; y++) {
      for (int x = 0; x < probe_res; x++) {
        ivec2 texel = ivec2(x, y);
        vec3 dir = oct_texel_dir(texel, probe_res, ray_jitter);
        if (dot(dir, pn) <= 0.0) {
          continue;
        }
        vec3 L = texelFetch(probe_filtered, pr * probe_res + texel, 0).rgb - mean;
        sh9_basis(dir, b);
        float sa = oct_texel_solid_angle(texel, probe_res);
        for (int k = 0; k < 9; k++) {
          c[k] += L * (b[k] * sa);
        }
      }
    }
    /* below the horizon, the mean above it: projected exactly over the whole sphere */
    c[0] += mean * (SH_Y0 * 4.0 * 3.14159265358979);
  }
  for (int k = 0; k < 9; k++) {
    imageStore(out_image, pr * 3 + ivec2(k % 3, k / 3), vec4(c[k], 1.0));
  }
}
