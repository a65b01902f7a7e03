/* Lumen GI: where voxel lighting lives (voxel_lighting.py; the update writes it,
 * voxel_lighting_lib.glsl samples it; needs global_sdf_lib.glsl).
 *
 * The voxels are the global SDF's: for each of its 4 clipmap levels, the same origin, voxel size,
 * N and toroidal texel t (a global-SDF hit in level k reads level k's voxels, no lookup); 6 faces
 * per voxel in the order of SC_AXES (+X -X +Y -Y +Z -Z). Face f of a voxel: rgb = final light
 * (surface cache) of the surface that a ray from the voxel's centre along axis f meets within
 * VL_REACH voxels, i.e. the light leaving that surface toward -axis; a says where the ray met it:
 * +-(1 + s), s = the hit's distance from the centre in voxels, + when the surface cache lit it
 * (rgb is its light), - when no card saw it (rgb 0: the surface is there, its light unknown);
 * a = 0 where no surface was met, and for every face of a voxel inside a solid (VL_INSIDE).
 * One RGBA16F 2D texture, 24 N x N^2:
 * (level k, face f, voxel texel t) is texel x = (k * 6 + f) * N + t.x, y = t.z * N + t.y.
 * Tiles (the update's object lists): 4x4x4 voxels of a level's own cells, VL_TILE_OBJECTS object
 * indices each (R32F, -1 after the last): tile (x, y, z) of level k at texels
 * [x * VL_TILE_OBJECTS, +VL_TILE_OBJECTS) of row k T^2 + z T + y, T = N / 4.
 * Update list (one level at a time): R32F, VL_LIST_WIDTH wide, entry i at (i % width, i / width):
 * voxel texel index x + N (y + N z), -1 past the last.
 */
#define VL_FACES 6
#define VL_TILE 4
#define VL_TILE_OBJECTS 32
#define VL_LIST_WIDTH 256
/* A voxel centre whose global SDF texel is below VL_INSIDE x the thin-wall margin (half the
 * largest mesh voxel, gsdf.band.y) lies inside a solid (the mesh SDFs are clamped a few of their
 * voxels inside, so depth is not known beyond that): it holds no faces and no lookup uses it. */
#define VL_INSIDE -0.5
#define VL_REACH 1.5

/* The code a face stores for a surface met s voxels ahead of the centre (lit or not), and back:
 * the distance of a face's code (-9 where no surface was met). */
float vl_face_code(float s, bool lit)
{
  float code = 1.0 + clamp(s, 0.0, VL_REACH);
  return lit ? code : -code;
}

float vl_face_offset(float code)
{
  return abs(code) > 0.5 ? abs(code) - 1.0 : -9.0;
}

ivec2 vl_texel(int level, int face, ivec3 t, int n)
{
  return ivec2((level * VL_FACES + face) * n + t.x, t.z * n + t.y);
}

ivec2 vl_tile_texel(int level, ivec3 tile, int n)
{
  int tn = n / VL_TILE;
  return ivec2(tile.x * VL_TILE_OBJECTS, level * tn * tn + tile.z * tn + tile.y);
}
