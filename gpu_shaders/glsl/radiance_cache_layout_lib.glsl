/* Lumen GI: the world radiance cache's layout (radiance_cache.py). Needs the push constant
 * rc_camera (xyz: the camera, w: level-0 probe spacing s0 in metres; w <= 0: the cache is off).
 *
 * RC_LEVELS clipmaps of RC_N^3 cells around the camera; level k has spacing s0 * 2^k, its first
 * world cell floor(camera / s_k) - RC_N / 2, and a probe at each cell centre (cell + 0.5) s_k.
 * Cells are addressed toroidally (texel = world cell mod RC_N, as the global SDF's), so a
 * probe keeps its texel while the clipmap scrolls; slots remember their world cell to tell.
 * Textures: cells / marks R32F (RC_N^2 wide, RC_N * RC_LEVELS tall: x + N y, z + N level);
 * slot tables RC_SLOT_W slots per row; the atlas RC_RES x RC_RES octahedral texels per slot.
 * RC_RADIUS: the interpolation footprint (a point is at most sqrt(3) spacings from each of its
 * 8 probes), also the radius of the probes' parallax sphere and what their visibility test
 * needs clear; a screen-probe ray covers 2 RC_RADIUS spacings (footprint + skipped distance).
 */
#ifndef LUMEN_RC_LAYOUT_LIB
#define LUMEN_RC_LAYOUT_LIB
#define RC_N 32
#define RC_LEVELS 4
#define RC_RES 8
#define RC_SLOT_W 64
#define RC_RADIUS 1.7320508

float rc_spacing(int k)
{
  return rc_camera.w * float(1 << k);
}

ivec3 rc_origin(int k)
{
  return ivec3(floor(rc_camera.xyz / rc_spacing(k))) - RC_N / 2;
}

ivec3 rc_imod(ivec3 a)
{
  return a - RC_N * ivec3(floor(vec3(a) / float(RC_N)));
}

/* The finest level whose 8 probes around p all lie inside it; -1: none (or the cache is off). */
int rc_level(vec3 p)
{
  if (rc_camera.w <= 0.0) {
    return -1;
  }
  for (int k = 0; k < RC_LEVELS; k++) {
    ivec3 i0 = ivec3(floor(p / rc_spacing(k) - 0.5));
    ivec3 o = rc_origin(k);
    if (all(greaterThanEqual(i0, o)) && all(lessThan(i0 + 1, o + RC_N))) {
      return k;
    }
  }
  return -1;
}

/* How far a screen-probe ray at level k traces before the cache takes over. */
float rc_trace_distance(int k)
{
  return 2.0 * RC_RADIUS * rc_spacing(k);
}

ivec2 rc_cell_texel(int k, ivec3 cell)
{
  ivec3 t = rc_imod(cell);
  return ivec2(t.x + RC_N * t.y, t.z + RC_N * k);
}

/* The world cell the clipmap holds at texel tx now (and its level). */
ivec3 rc_texel_cell(ivec2 tx, out int k)
{
  k = tx.y / RC_N;
  ivec3 t = ivec3(tx.x % RC_N, tx.x / RC_N, tx.y % RC_N);
  ivec3 o = rc_origin(k);
  return o + rc_imod(t - o);
}

vec3 rc_probe_pos(int k, ivec3 cell)
{
  return (vec3(cell) + 0.5) * rc_spacing(k);
}

ivec2 rc_slot_texel(int slot)
{
  return ivec2(slot % RC_SLOT_W, slot / RC_SLOT_W);
}

#endif /* LUMEN_RC_LAYOUT_LIB */
