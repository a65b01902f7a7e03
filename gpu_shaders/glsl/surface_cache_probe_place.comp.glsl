#include "sdf_ray_lib.glsl"
#include "surface_cache_pages_lib.glsl"
#include "surface_cache_probe_lib.glsl"
/* Surface cache indirect light, step 0: place. One invocation per probe of this frame's tiles: the
 * probe's texel this frame (scp_texel: jittered per frame, a covered texel is no site) and its
 * surface, written once for its 16 rays. Why a pass: the trace ran this in each of a probe's 16
 * ray invocations (a field sample per candidate texel and a matrix inverse, 16 times over; with
 * the ray LOD most of them then traced nothing).
 * Inputs: texel_card, card tables and layers, the mesh SDFs, sc_pages; frame.
 * Outputs: out_image (one texel per probe): world normal xyz, w = card row + 1 (0: no probe);
 * probe_pos_out: world position xyz, w = the object's voxel; probe_room_out: x = the scene
 * field at the probe's lifted end (gi_lifted), which every visibility test against this probe
 * reads (surface_cache_probe_sh, _indirect: gi_visible_between), sampled here once.
 */
void main()
{
  ivec2 gid = ivec2(gl_GlobalInvocationID.xy);
  ivec2 probe = scp_page_tile(gid.x / SCP_TILE) * SCP_TILE + ivec2(gid.x % SCP_TILE, gid.y);
  ivec2 grid = imageSize(out_image);
  if (probe.x >= grid.x || probe.y >= grid.y) {
    return;
  }
  ivec2 texel;
  int row;
  if (!scp_texel(probe, frame, texel, row)) {
    imageStore(out_image, probe, vec4(0.0));
    imageStore(probe_pos_out, probe, vec4(0.0));
    imageStore(probe_room_out, probe, vec4(0.0));
    return;
  }
  vec3 p, n;
  int obj;
  scp_surface(texel, row, p, n, obj);
  imageStore(out_image, probe, vec4(n, float(row + 1)));
  float voxel = gi_object_voxel(obj);
  imageStore(probe_pos_out, probe, vec4(p, voxel));
  float h;
  int o;
  imageStore(probe_room_out, probe, vec4(sdf_scene(gi_lifted(p, n, voxel), h, o), 0.0, 0.0, 0.0));
}
