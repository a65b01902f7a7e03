/* Screen probes, temporal filter: E = mix(history, E_new, blend) per pixel. The engine passes
 * blend = 1 when the history is unusable (first frame, camera moved, scene changed), a running
 * mean 1 / (n + 1) while an F12 render accumulates, and an exponential 1 / history in the viewport.
 * Inputs: indirect_new, indirect_history; blend. Output out_image: E.rgb, w copied from new.
 */
void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(out_image);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  vec4 e = texelFetch(indirect_new, px, 0);
  vec4 h = texelFetch(indirect_history, px, 0);
  imageStore(out_image, px, vec4(mix(h.rgb, e.rgb, blend), e.w));
}
