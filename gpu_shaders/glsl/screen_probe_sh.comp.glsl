/* Screen probes to spherical harmonics (lecture: "Convert Probe Radiance to 3rd order SH"): per
 * probe, c_k = sum over its octahedral texels of L * Y_k(dir) * texel solid angle (exact solid
 * angles, octahedral_lib.glsl), dir the direction actually traced (ray_jitter).
 * Inputs: probe_info, probe_filtered (radiance rgb); probe_res, ray_jitter.
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
    for (int y = 0; y < probe_res; y++) {
      for (int x = 0; x < probe_res; x++) {
        ivec2 texel = ivec2(x, y);
        vec3 L = texelFetch(probe_filtered, pr * probe_res + texel, 0).rgb;
        float b[9];
        sh9_basis(oct_texel_dir(texel, probe_res, ray_jitter), b);
        float sa = oct_texel_solid_angle(texel, probe_res);
        for (int k = 0; k < 9; k++) {
          c[k] += L * (b[k] * sa);
        }
      }
    }
  }
  for (int k = 0; k < 9; k++) {
    imageStore(out_image, pr * 3 + ivec2(k % 3, k / 3), vec4(c[k], 1.0));
  }
}
