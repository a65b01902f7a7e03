/* The viewport's progressive direct light (direct_light.py: Progressive): this redraw's part of
 * the light samples blended into the running means, mean = mix(mean, new, blend) with
 * blend = 1 / (parts so far + 1).
 * Inputs: new_direct, new_combined (the direct pass's outputs), blend.
 * Outputs (read and written in place): direct_mean, combined_mean. */
void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(direct_mean);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  imageStore(direct_mean, px, mix(imageLoad(direct_mean, px), texelFetch(new_direct, px, 0), blend));
  imageStore(combined_mean, px,
             mix(imageLoad(combined_mean, px), texelFetch(new_combined, px, 0), blend));
}
