/* Screen probes, placement: one probe per PROBE_TILE x PROBE_TILE pixel tile, on a G-buffer pixel.
 * The pixel is jittered every frame (tile_jitter, from a 16-point Hammersley set, lecture: "Screen
 * Probe Jitter"); if it shows no surface, the tile centre and then the tile's corners are tried.
 * Inputs: gbuf_position, gbuf_normal; push constants cam_pos, probe_tile, tile_jitter (pixels).
 * Outputs: out_image (probe_info) = world position xyz, w = distance to the camera (0: no probe);
 * probe_normal_out = world normal xyz (turned to the camera), w = pixel index x + y * width.
 */
void main()
{
  ivec2 pr = ivec2(gl_GlobalInvocationID.xy);
  ivec2 grid = imageSize(out_image);
  if (pr.x >= grid.x || pr.y >= grid.y) {
    return;
  }
  ivec2 size = textureSize(gbuf_position, 0);
  ivec2 base = pr * probe_tile;
  ivec2 tries[6] = ivec2[6](ivec2(tile_jitter), ivec2(probe_tile / 2), ivec2(1, 1),
                            ivec2(probe_tile - 2, 1), ivec2(1, probe_tile - 2),
                            ivec2(probe_tile - 2, probe_tile - 2));
  for (int k = 0; k < 6; k++) {
    ivec2 px = min(base + tries[k], size - 1);
    vec4 pos = texelFetch(gbuf_position, px, 0);
    if (pos.w < 0.5) {
      continue;
    }
    vec3 n = normalize(texelFetch(gbuf_normal, px, 0).xyz);
    if (dot(n, cam_pos - pos.xyz) < 0.0) {
      n = -n;
    }
    imageStore(out_image, pr, vec4(pos.xyz, max(distance(pos.xyz, cam_pos), 1e-4)));
    imageStore(probe_normal_out, pr, vec4(n, float(px.x + px.y * size.x)));
    return;
  }
  imageStore(out_image, pr, vec4(0.0));
  imageStore(probe_normal_out, pr, vec4(0.0, 0.0, 1.0, -1.0));
}
