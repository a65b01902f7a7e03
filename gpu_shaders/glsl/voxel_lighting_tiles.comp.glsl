#include "sdf_lib.glsl"
#include "global_sdf_lib.glsl"
#include "voxel_lighting_layout_lib.glsl"
/* Voxel lighting, step 1 (a light pass: llvmpipe runs every invocation of a shader through all of
 * its code, so step 2's heavy shader must only see the voxels that need it). One invocation per
 * tile of 4x4x4 voxels of one clipmap level: thread (x, y) is tile (x, y % T, y / T), T = N / 4,
 * in the level's own cells (cell = origin + 4 * tile + 0..3, no toroidal wrap inside a tile).
 *   - the objects near the tile (the lecture's "filter most objects out by 4x4x4 tiles"): the
 *     VL_TILE_OBJECTS whose bounding sphere comes nearest to the tile's box, among those within
 *     vl_reach of it (sorted, nearest first), so step 2's short rays test a few objects, not all;
 *     never one diffuse rays do not see (object table texel 9 z = 1, Ray Visibility > Diffuse
 *     off): the voxels do not hold its light, and a far GI ray's search does not find it
 *   - every voxel of the tile cleared (6 empty faces)
 *   - the voxels near a surface (global SDF texel <= a voxel + the thin-wall margins; the same
 *     voxel, so no interpolation) and not inside a solid (a lookup never uses those, see
 *     voxel_lighting_lib.glsl) appended to the update list (one atomic add per tile); a list
 *     full at vl_capacity leaves the rest empty: their hits read the surface cache
 * Push constants: vl_level, vl_reach (metres), vl_capacity.
 * Images: out_image (R32F object lists), vl_faces_out (RGBA16F faces), vl_list_out (R32F voxel
 * texel index x + N (y + N z), row-major VL_LIST_WIDTH wide), vl_counter (R32I, 1 texel: entries
 * appended, cleared before the pass). Layouts in voxel_lighting_layout_lib.glsl.
 */
void main()
{
  ivec2 id = ivec2(gl_GlobalInvocationID.xy);
  int n = textureSize(gsdf_level0, 0).x;
  int tn = n / VL_TILE;
  if (id.x >= tn || id.y >= tn * tn) {
    return;
  }
  ivec3 tile = ivec3(id.x, id.y % tn, id.y / tn);
  vec4 info = gsdf_origin(vl_level);
  ivec3 o = ivec3(round(info.xyz));
  vec3 lo = vec3(o + tile * VL_TILE) * info.w;
  vec3 he = vec3(0.5 * float(VL_TILE) * info.w);
  vec3 centre = lo + he;
  float dist[VL_TILE_OBJECTS];
  int idx[VL_TILE_OBJECTS];
  int count = 0;
  int objects = sdf_object_count();
  for (int i = 0; i < objects; i++) {
    vec4 sphere = sdf_object_texel(i, 8);
    float d = length(max(abs(sphere.xyz - centre) - he, vec3(0.0))) - sphere.w;
    if (d >= vl_reach || sdf_object_texel(i, 9).z >= 1.0) {
      continue;                   /* out of reach, or diffuse rays do not see it */
    }
    int j;
    if (count < VL_TILE_OBJECTS) {
      j = count;
      count++;
    }
    else if (d < dist[VL_TILE_OBJECTS - 1]) {
      j = VL_TILE_OBJECTS - 1;
    }
    else {
      continue;
    }
    while (j > 0 && dist[j - 1] > d) {
      dist[j] = dist[j - 1];
      idx[j] = idx[j - 1];
      j--;
    }
    dist[j] = d;
    idx[j] = i;
  }
  ivec2 at = vl_tile_texel(vl_level, tile, n);
  for (int j = 0; j < VL_TILE_OBJECTS; j++) {
    imageStore(out_image, at + ivec2(j, 0), vec4(j < count ? float(idx[j]) : -1.0, 0.0, 0.0, 0.0));
  }

  float near = info.w + 2.0 * gsdf.band.y;
  uint mask[2] = uint[2](0u, 0u);
  int near_count = 0;
  for (int k = 0; k < VL_TILE * VL_TILE * VL_TILE; k++) {
    ivec3 t = gsdf_imod(o + tile * VL_TILE + ivec3(k & 3, (k >> 2) & 3, k >> 4), n);
    for (int f = 0; f < VL_FACES; f++) {
      imageStore(vl_faces_out, vl_texel(vl_level, f, t, n), vec4(0.0));
    }
    float d = gsdf_fetch(vl_level, t);
    if (count > 0 && d <= near && d >= VL_INSIDE * gsdf.band.y) {
      mask[k >> 5] |= 1u << uint(k & 31);
      near_count++;
    }
  }
  if (near_count == 0) {
    return;
  }
  int slot = imageAtomicAdd(vl_counter, ivec2(0, 0), near_count);
  for (int k = 0; k < VL_TILE * VL_TILE * VL_TILE && slot < vl_capacity; k++) {
    if ((mask[k >> 5] & (1u << uint(k & 31))) == 0u) {
      continue;
    }
    ivec3 t = gsdf_imod(o + tile * VL_TILE + ivec3(k & 3, (k >> 2) & 3, k >> 4), n);
    imageStore(vl_list_out, ivec2(slot % VL_LIST_WIDTH, slot / VL_LIST_WIDTH),
               vec4(float(t.x + n * (t.y + n * t.z)), 0.0, 0.0, 0.0));
    slot++;
  }
}
