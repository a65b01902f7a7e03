/* Temporal accumulation of a GI method's irradiance (gi_methods.py: SSGI, RSM): out =
 * mix(history, new, blend); blend 1 / (n + 1) is F12's running mean, 1 / history the viewport's
 * exponential window. Inputs: e_new, e_history; push blend, mix_alpha (1: w is averaged too, the
 * anti-aliasing's Combined, whose alpha is coverage with Film > Transparent; 0: w is new's flag).
 * Output out_image.
 */
void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(out_image);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  vec4 e = texelFetch(e_new, px, 0);
  vec4 h = texelFetch(e_history, px, 0);
  imageStore(out_image, px,
             vec4(mix(h.rgb, e.rgb, blend), mix_alpha != 0 ? mix(h.w, e.w, blend) : e.w));
}
