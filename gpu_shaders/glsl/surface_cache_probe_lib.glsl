#include "sdf_lib.glsl"
#include "sdf_ray_lib.glsl"
#include "surface_cache_lib.glsl"
#include "sampling_lib.glsl"
#include "surface_cache_pages_lib.glsl"
/* Lumen GI: surface-cache radiosity probes (lecture: "Indirect Lighting": 2x2 probes per 8x8 tile,
 * each probe covering 4x4 texels, 16 rays, jittered placement and directions).
 * Needs sdf_lib.glsl, sdf_ray_lib.glsl, surface_cache_lib.glsl, sampling_lib.glsl; texel_card.
 * card_packing.py aligns every card of the lighting atlas to 4 texels, so a probe's 4x4 block
 * belongs to one card (or none). A probe sits on one texel of its block: the frame's jittered
 * texel, else the next valid one in scan order; its rays are a 16-point Hammersley set over the
 * hemisphere of its normal (uniform: pdf 1 / (2 pi), so every ray has the same SH weight),
 * rotated per probe and frame.
 */
#define SCP_SIZE 4
#define SCP_RAYS 16
/* The frame whose jitter a probe's rays were traced with (its tile's last update). */
int scp_probe_frame(ivec2 probe)
{
  return int(texelFetch(sc_tile_frame, probe / SCP_TILE, 0).x + 0.5);
}

uint scp_seed(ivec2 probe, int frame)
{
  return pcg_hash(uint(probe.x) + 8191u * uint(probe.y)) ^ pcg_hash(uint(frame) * 0x9e3779b9u + 17u);
}

/* World position and normal of lighting texel `texel` on card row `row`. */
void scp_surface(ivec2 texel, int row, out vec3 p, out vec3 n, out int obj)
{
  vec3 pl, nl, albedo, emissive;
  vec4 t0 = sc_card(row, 0);
  sc_texel_surface(row, texel - ivec2(t0.zw + 0.5), pl, nl, albedo, emissive);
  obj = int(t0.x + 0.5);
  mat4 w2l = sc_object_w2l(obj);
  p = (inverse(w2l) * vec4(pl, 1.0)).xyz;
  n = normalize(transpose(mat3(w2l)) * nl);
}

/* The probe's texel; false when its block holds no surface. row: the texel's card row. A texel
 * whose ray origin (one voxel off the surface) lies within half a voxel of any surface is no
 * site for a probe: it is covered (a floor under a wall standing on it) or in a crevice, and its
 * rays would start inside a wall and gather the light of its other side. */
bool scp_texel(ivec2 probe, int frame, out ivec2 texel, out int row)
{
  int start = int(scp_seed(probe, frame) & 15u);
  for (int i = 0; i < SCP_RAYS; i++) {
    int k = (start + i) & 15;
    texel = probe * SCP_SIZE + ivec2(k & 3, k >> 2);
    row = int(texelFetch(texel_card, texel, 0).x);
    if (row < 0) {
      continue;
    }
    vec4 t1 = sc_card(row, 1);
    ivec2 ij = texel - ivec2(sc_card(row, 0).zw + 0.5);
    if (texelFetch(sc_albedo, ivec2(t1.xy + 0.5) + ij, 0).a > 0.5) {
      vec3 p, n;
      int obj;
      scp_surface(texel, row, p, n, obj);
      float h;
      int o;
      float v = gi_object_voxel(obj);
      if (sdf_scene(p + n * v, h, o) > GI_HIT_VOXELS * h) {
        return true;
      }
    }
  }
  row = -1;
  return false;
}

/* Ray k of a probe with normal n: uniform over the hemisphere, stratified. Slot k = x + 4 y of
 * the 4x4 ray block takes Hammersley point 4 x + y, so each row y of the block (what a probe
 * far from the camera traces alone: surface_cache_probe_trace's ray LOD) holds points spread
 * over the whole
 * hemisphere (cos theta in four bands), not one band of it. */
vec3 scp_dir(ivec2 probe, int frame, int k, vec3 n)
{
  uint s = scp_seed(probe, frame) * 747796405u + 1u;
  vec2 rot = vec2(float(s & 0xffffu), float(s >> 16u)) / 65536.0;
  int j = (k & 3) * 4 + (k >> 2);
  vec2 u = fract(hammersley(uint(j), uint(SCP_RAYS)) + rot);
  float z = u.x;
  float r = sqrt(max(0.0, 1.0 - z * z));
  float phi = 6.28318530717958648 * u.y;
  return tangent_frame(n) * vec3(r * cos(phi), r * sin(phi), z);
}
