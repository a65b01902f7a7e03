/* Screen probes, tracing: one ray per octahedral texel of every probe (probe_res^2 per probe,
 * the whole sphere in world-space directions so that neighbours' texels match), through
 * gi_trace_lib.glsl (mesh SDFs near, global SDF far, the surface cache at hits, sky on a miss).
 * Directions are jittered inside their texel by ray_jitter (the same for every probe of a frame).
 * Rays start one voxel of the nearest object off the probe's surface along its normal.
 * Inputs: probe_info, probe_normal; push constants probe_res, ray_jitter, t_max.
 * Output out_image (probe atlas, probe (i, j) at texels [i*res, (i+1)*res) x [j*res, ...)):
 * radiance rgb, a = hit distance (t_max on a miss, -1 where there is no probe).
 */
void main()
{
  ivec2 tx = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(out_image);
  if (tx.x >= size.x || tx.y >= size.y) {
    return;
  }
  ivec2 pr = tx / probe_res;
  ivec2 texel = tx - pr * probe_res;
  vec4 info = texelFetch(probe_info, pr, 0);
  if (info.w <= 0.0) {
    imageStore(out_image, tx, vec4(0.0, 0.0, 0.0, -1.0));
    return;
  }
  vec3 n = texelFetch(probe_normal, pr, 0).xyz;
  vec3 dir = oct_texel_dir(texel, probe_res, ray_jitter);
  float h;
  int obj;
  sdf_scene(info.xyz, h, obj);
  vec3 o = info.xyz + n * max(gi_object_voxel(max(obj, 0)), 1e-3);
  float t, w;
  vec3 L = gi_radiance(o, dir, t_max, t, w);
  imageStore(out_image, tx, vec4(L, t));
}
