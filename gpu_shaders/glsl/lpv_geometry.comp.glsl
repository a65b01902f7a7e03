#include "sdf_lib.glsl"
#include "lpv_lib.glsl"
/* LPV geometry occlusion (lpv.py): per cell, how much of the light crossing to its +x, +y, +z
 * neighbour gets through, from the mesh SDFs (sdf_scene) instead of the paper's geometry volume
 * of surfels (Kaplanyan and Dachsbacher 2010: a fuzzy blocking potential |n . w| x coverage).
 * The segment between the two cell centres (length h, along axis a) is sampled at 5 points,
 * 0.25 h apart (d0..d4). A plane of normal n crossing it gives d0 + d4 = h |n . a|, and when it
 * crosses between 0.125 h and 0.875 h it passes within h/8 of an interior sample (d1..d3):
 *     B = clamp((d0 + d4 - 2 m) / h) x clamp((h/4 + v/2 - m) / (h/8)),  m = min(d1, d2, d3)
 * (1 inside a solid, m <= 0), T = 1 - B. v/2, half the nearest mesh SDF's voxel, is the
 * thin-wall margin (sdf_ray_lib.glsl's rule: a plane's SDF does not reach 0 at its voxel
 * resolution; without it the single-sided wall of test_lpv.py let 0.20 of its front's light
 * behind it, 0.26 with no occlusion at all). So a wall across the segment blocks it; a floor
 * beside it (parallel: d0 = d4 = m) does not, and neither does a surface just behind a cell
 * centre (the layer a surface's virtual lights are injected into, half a cell in front of it):
 * a plain threshold on min d did both, so whether light left a wall or spread along a floor
 * depended on how the grid fell on them (relMSE 0.08 to 0.15 on the Cornell box from 24 to 32
 * cells). Output out_image: (T+x, T+y, T+z, 1) at the cell's texel (lpv_lib.glsl's layout).
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
    float m = 1e30, d0 = 0.0, d4 = 0.0, margin = 0.0;
    for (int k = 0; k <= 4; k++) {
      float voxel;
      int nearest;
      float d = sdf_scene(centre + axis * (0.25 * h * float(k)), voxel, nearest);
      if (k > 0 && k < 4 && d < m) {
        m = d;
        margin = 0.5 * voxel;
      }
      d0 = k == 0 ? d : d0;
      d4 = k == 4 ? d : d4;
    }
    float B = m <= 0.0 ? 1.0 : clamp((d0 + d4 - 2.0 * m) / h, 0.0, 1.0) *
                               clamp((0.25 * h + margin - m) / (0.125 * h), 0.0, 1.0);
    T[a] = 1.0 - B;
  }
  imageStore(out_image, t, vec4(T, 1.0));
}
