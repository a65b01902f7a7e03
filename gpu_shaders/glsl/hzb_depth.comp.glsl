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

/* One work group (8 x 8 pixels) loads the window depths of its pixels and their one-pixel
 * border (10 x 10) once into shared memory: each depth is a position fetch and a matrix product,
 * and the 3x3 MIN needs every one nine times (measured on llvmpipe at 640 x 360: 11.3 ms with
 * nine per pixel, bench/glsl_ab.py). */
#define HZB_TILE 8                /* hzb.py's DEPTH pass: 8 x 8 work groups */
#define HZB_SIDE (HZB_TILE + 2)
shared float s_depth[HZB_SIDE * HZB_SIDE];

void main()
{
  ivec2 size = textureSize(gbuf_position, 0);
  ivec2 corner = ivec2(gl_WorkGroupID.xy) * HZB_TILE - 1;
  for (int k = int(gl_LocalInvocationIndex); k < HZB_SIDE * HZB_SIDE;
       k += HZB_TILE * HZB_TILE) {
    ivec2 q = corner + ivec2(k % HZB_SIDE, k / HZB_SIDE);
    bool inside = all(greaterThanEqual(q, ivec2(0))) && all(lessThan(q, size));
    s_depth[k] = inside ? window_depth(q) : 1.0;
  }
  barrier();
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  ivec2 l = ivec2(gl_LocalInvocationID.xy) + 1;
  float z = 1.0;
  for (int j = -1; j <= 1; j++) {
    for (int i = -1; i <= 1; i++) {
      z = min(z, s_depth[(l.y + j) * HZB_SIDE + l.x + i]);
    }
  }
  imageStore(hzb, px, vec4(z, 0.0, 0.0, 0.0));
}
