#include "sdf_lib.glsl"
/* Lumen GI: build (or scroll) one clipmap level of the global SDF from the mesh SDFs
 * (needs sdf_lib.glsl before it and global_sdf_lib.glsl's gsdf_imod).
 *
 * Image gsdf_out (R16F or R32F 3D, N^3). Texel t holds world cell
 *   cell = origin + ((t - origin) mod N)      (toroidal addressing: a world cell keeps its texel
 * while the level scrolls), whose centre is (cell + 0.5) * voxel in world metres.
 * Push constants:
 *   build_origin  xyz: the level's first cell (integers in float), w: voxel size (m)
 *   build_prev    xyz: the previous first cell, w > 0.5: scroll (only cells that were outside the
 *                 previous box are evaluated; the others keep their values)
 *   build_band    stored values are min(d, band): beyond the band only a conservative bound
 *   build_box     w > 0.5: refresh only the world cells [xyz, build_box_end.xyz) that lie in the
 *                 level (objects moved there: GlobalSDF.update's dirty boxes); the dispatch
 *                 covers the box, not the level
 * sdf_scene_reach: the object grid's value where it is exact below the band, else every object
 * (in open space at the coarse levels, whose band reaches past the grid's margin).
 */
void main()
{
  ivec3 t = ivec3(gl_GlobalInvocationID.xyz);
  int n = imageSize(gsdf_out).x;
  ivec3 o = ivec3(round(build_origin.xyz));
  ivec3 cell;
  if (build_box.w > 0.5) {
    cell = ivec3(round(build_box.xyz)) + t;
    if (any(greaterThanEqual(cell, ivec3(round(build_box_end.xyz))))
        || any(lessThan(cell, o)) || any(greaterThanEqual(cell, o + n))) {
      return;
    }
    t = gsdf_imod(cell, n);            /* the texel that holds the world cell */
  }
  else {
    if (any(greaterThanEqual(t, ivec3(n)))) {
      return;
    }
    cell = o + gsdf_imod(t - o, n);
  }
  if (build_prev.w > 0.5) {
    ivec3 q = ivec3(round(build_prev.xyz));
    if (all(greaterThanEqual(cell, q)) && all(lessThan(cell, q + n))) {
      return;
    }
  }
  vec3 p = (vec3(cell) + 0.5) * build_origin.w;
  float h;
  int nearest;
  float d = sdf_scene_reach(p, build_band, h, nearest);    /* exact below the band */
  imageStore(gsdf_out, t, vec4(min(d, build_band), 0.0, 0.0, 0.0));
}
