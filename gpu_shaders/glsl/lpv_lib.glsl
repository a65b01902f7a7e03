/* Light propagation volumes (lpv.py): the grid's layout and its SH lobes, shared by the passes.
 * The grid is dims.x x dims.y x dims.z cubic cells of side h whose first corner is origin
 * (push constants grid_origin = (origin, h), grid_dims = (dims, 0)); it is stored in 2D
 * RGBA32F textures of dims.x x (dims.y dims.z) texels, cell (x, y, z) at texel (x, y + dims.y z),
 * one texture per colour channel holding that channel's 4 SH coefficients in sh_lib.glsl's order
 * (Y00, Y1-1 y, Y10 z, Y11 x). A cell holds the INTENSITY (W/sr) its virtual point lights send
 * in direction w, I(w) = sum_i c_i Y_i(w); its total flux is 4 pi Y00 c0 = 2 sqrt(pi) c0.
 */
#define LPV_PI 3.14159265358979

ivec2 lpv_texel(ivec3 c, ivec3 dims)
{
  return ivec2(c.x, c.y + dims.y * c.z);
}

ivec3 lpv_cell(ivec2 t, ivec3 dims)
{
  return ivec3(t.x, t.y % dims.y, t.y / dims.y);
}

bool lpv_inside(ivec3 c, ivec3 dims)
{
  return all(greaterThanEqual(c, ivec3(0))) && all(lessThan(c, dims));
}

/* SH of max(0, n . w): (sqrt(pi) / 2, sqrt(pi / 3) n); a Lambertian emitter of flux Phi and
 * normal n has intensity Phi / pi max(0, n . w), i.e. Phi / pi x this lobe */
vec4 lpv_lobe(vec3 n)
{
  return vec4(0.886226925452758, 1.02332670794649 * vec3(n.y, n.z, n.x));
}

/* the basis at a unit direction: I(w) = dot(c, lpv_basis(w)) */
vec4 lpv_basis(vec3 w)
{
  return vec4(0.28209479177387814, 0.4886025119029199 * vec3(w.y, w.z, w.x));
}
