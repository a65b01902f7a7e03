/* LPV geometry occlusion (lpv.py): per cell, how much of the light crossing to its +x, +y, +z
 * neighbour gets through, from the mesh SDFs (sdf_scene) instead of the paper's geometry volume
 * of surfels (Kaplanyan and Dachsbacher 2010, "fuzzy occlusion"). The segment between the two
 * cell centres (length h) is sampled at 5 points, 0.25 h apart: a surface crossing it comes
 * within 0.125 h of a sample, so min d <= h/8 blocks fully; d >= 3h/8 lets everything through;
 * linear in between (a fuzzy blocking potential). Inside a solid d < 0: blocked.
 * Output out_image: (T+x, T+y, T+z, 1) at the cell's texel (lpv_lib.glsl's layout).
 */
void main()
{
  ivec2 t = ivec2(gl_GlobalInvocationID.xy);
  ivec3 dims = grid_dims.xyz;
  if (t.x >= dims.x || t.y >= dims.y * dims.z) {
    return;
  }
  ivec3 c = lpv_cell(t, dims);
  float h = grid_origin.w;
  vec3 centre = grid_origin.xyz + (vec3(c) + 0.5) * h;
  vec3 T = vec3(1.0);
  for (int a = 0; a < 3; a++) {
    vec3 axis = vec3(0.0);
    axis[a] = 1.0;
    float dmin = 1e30;
    for (int k = 0; k <= 4; k++) {
      float voxel;
      int nearest;
      dmin = min(dmin, sdf_scene(centre + axis * (0.25 * h * float(k)), voxel, nearest));
    }
    T[a] = clamp((dmin - 0.125 * h) / (0.25 * h), 0.0, 1.0);
  }
  imageStore(out_image, t, vec4(T, 1.0));
}
