/* The viewport's progressive direct light (direct_light.py: Progressive): this redraw's part of
 * each pixel's light samples blended into its running means, mean = mix(mean, new, 1 / (c + 1))
 * for a pixel whose mean holds c parts (c = 0: the new part is the mean), and c + 1 stored.
 * Pixels whose mean is whole (c >= frames) are left as they are (the direct pass wrote nothing
 * there).
 * Inputs: new_direct, new_combined (the direct pass's outputs), frames.
 * Read and written: direct_mean, combined_mean, parts (R32F). */
void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(direct_mean);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  float c = imageLoad(parts, px).r;
  if (c >= float(frames) - 0.5) {
    return;
  }
  vec4 d = texelFetch(new_direct, px, 0);
  vec4 m = texelFetch(new_combined, px, 0);
  if (c > 0.5) {                     /* (a new mean's texels are not read: they may be NaN) */
    d = mix(imageLoad(direct_mean, px), d, 1.0 / (c + 1.0));
    m = mix(imageLoad(combined_mean, px), m, 1.0 / (c + 1.0));
  }
  imageStore(direct_mean, px, d);
  imageStore(combined_mean, px, m);
  imageStore(parts, px, vec4(c + 1.0));
}
