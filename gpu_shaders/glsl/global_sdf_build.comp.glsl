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
 * (in open space at the coarse levels, whose band reaches past the grid's margin); a box refresh
 * visits instead only its block's candidates (build_list, flat in R32F texels: per block of
 * build_list_sub^3 cells of the box, x fastest, its first entry and count, then the entries:
 * object rows whose bounding spheres come within the band of one of the block's cell centres;
 * every other one is at least the band away, and the stored value is clamped there, so the
 * texels are the same).
 */
float build_list_at(int k)
{
  int width = textureSize(build_list, 0).x;
  return texelFetch(build_list, ivec2(k % width, k / width), 0).x;
}

float build_scene(ivec3 cell, vec3 p, float band, out float h, out int nearest)
{
  if (build_list_sub < 0) {
    return sdf_scene_reach(p, band, h, nearest);
  }
  float best, bound;
  if (sdf_scene_grid(p, best, h, nearest, bound) && bound < min(best, band)) {
    best = 1e30;
    h = 1.0;
    nearest = -1;
    ivec3 first = ivec3(round(build_box.xyz));
    ivec3 blocks = (ivec3(round(build_box_end.xyz)) - first + build_list_sub - 1) / build_list_sub;
    ivec3 b = (cell - first) / build_list_sub;
    int j = b.x + blocks.x * (b.y + blocks.y * b.z);
    int start = int(build_list_at(2 * j) + 0.5);
    int count = int(build_list_at(2 * j + 1) + 0.5);
    for (int k = start; k < start + count; k++) {
      sdf_visit(int(build_list_at(k) + 0.5), p, best, h, nearest);
    }
    return best;
  }
  return min(best, bound);
}

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
  float d = build_scene(cell, p, build_band, h, nearest);    /* exact below the band */
  imageStore(gsdf_out, t, vec4(min(d, build_band), 0.0, 0.0, 0.0));
}
