/* Lumen GI G-buffer: one draw of every mesh triangle (world-space vertices, no index buffer).
 * Vertex inputs: pos, nor (world), albedo, emit (per corner, the triangle's material values).
 * Push constant: view_proj. Outputs (colour attachments 0..3, RGBA32F):
 *   out_position: world position xyz, w = 1 where a surface was drawn (0: background)
 *   out_normal:   world normal xyz (interpolated, normalised), w = 1
 *   out_albedo:   base colour rgb (linear), w = 1
 *   out_emission: emission colour x strength rgb, w = 1
 * The vertex and fragment stages are separated by the marker line "// FRAGMENT" (without the space).
 */
void main()
{
  v_pos = pos;
  v_nor = nor;
  v_albedo = albedo;
  v_emit = emit;
  gl_Position = view_proj * vec4(pos, 1.0);
}
//FRAGMENT
void main()
{
  out_position = vec4(v_pos, 1.0);
  vec3 n = v_nor;
  float len = length(n);
  out_normal = vec4(len > 0.0 ? n / len : vec3(0.0, 0.0, 1.0), 1.0);
  out_albedo = vec4(v_albedo, 1.0);
  out_emission = vec4(v_emit, 1.0);
}
