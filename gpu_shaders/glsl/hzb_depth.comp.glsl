/* HZB level 0 (hzb.py, SSGI): per pixel the MIN window depth (z_ndc * 0.5 + 0.5 of the frame's
 * view_proj, as the depth buffer holds it) over the pixel and its 8 neighbours; 1.0 (the far
 * plane) on the background: nothing there stops a ray.
 * Why the 3x3 MIN and not the pixel's own depth: a pixel shows its surface out to its corners,
 * half a pixel beyond its centre, and at a grazing angle the depth changes a lot within a pixel.
 * The window depth of a plane is affine in screen space, so at a corner it lies between the
 * centre depths of the pixels around that corner, never below their min: the 3x3 MIN bounds
 * everything the pixel shows, and a ray in front of it cannot touch the pixel's surface.
 * (The depth along a ray's screen line is affine too: a ray is a straight 3D line in (pixel x,
 * pixel y, window depth).)
 * Inputs: gbuf_position; push view_proj. Output: hzb (R32F atlas, mip_lib.glsl), level 0.
 */
float window_depth(ivec2 px)
{
  vec4 pos = texelFetch(gbuf_position, px, 0);
  if (pos.w < 0.5) {
    return 1.0;
  }
  vec4 h = view_proj * vec4(pos.xyz, 1.0);
  return clamp(h.z / h.w * 0.5 + 0.5, 0.0, 1.0);
}

void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = textureSize(gbuf_position, 0);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  float z = 1.0;
  for (int j = -1; j <= 1; j++) {
    for (int i = -1; i <= 1; i++) {
      ivec2 q = px + ivec2(i, j);
      if (q.x >= 0 && q.y >= 0 && q.x < size.x && q.y < size.y) {
        z = min(z, window_depth(q));
      }
    }
  }
  imageStore(hzb, px, vec4(z, 0.0, 0.0, 0.0));
}
