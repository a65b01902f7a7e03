/* Lumen GI: the world as a light (lumen_addon/sky.py). One RGBA32F sampler, sky_maps, holds
 * SkyMaps.atlas(): rows [0, H) the background map (2H x H, what the camera sees), then the ray
 * map (64 x 32: prefiltered over a ray's cone, the extracted sun left out: it is a light with
 * SDF shadows), then the irradiance map (32 x 16: E(n), the sun left out). Equirectangular as
 * Blender's Environment Texture: u = (pi - atan2(y, x)) / 2 pi, rows top (+Z) first. */
#define SKY_PI 3.14159265358979
#define SKY_RAY_SIZE ivec2(64, 32)
#define SKY_IRR_SIZE ivec2(32, 16)

vec3 sky_fetch(ivec2 origin, ivec2 size, vec3 d)
{
  d = normalize(d);
  /* atan(0, 0) is undefined in GLSL: a floor's normal, straight up, read a random column */
  float phi = (abs(d.x) + abs(d.y) > 1e-12) ? atan(d.y, d.x) : 0.0;
  vec2 uv = vec2((SKY_PI - phi) / (2.0 * SKY_PI), acos(clamp(d.z, -1.0, 1.0)) / SKY_PI);
  vec2 f = uv * vec2(size) - 0.5;
  ivec2 i0 = ivec2(floor(f));
  vec2 t = f - vec2(i0);
  int x0 = ((i0.x % size.x) + size.x) % size.x;      /* u wraps around */
  int x1 = (x0 + 1) % size.x;
  int y0 = clamp(i0.y, 0, size.y - 1);                /* v clamps at the poles */
  int y1 = clamp(i0.y + 1, 0, size.y - 1);
  vec3 a = mix(texelFetch(sky_maps, origin + ivec2(x0, y0), 0).rgb,
               texelFetch(sky_maps, origin + ivec2(x1, y0), 0).rgb, t.x);
  vec3 b = mix(texelFetch(sky_maps, origin + ivec2(x0, y1), 0).rgb,
               texelFetch(sky_maps, origin + ivec2(x1, y1), 0).rgb, t.x);
  return mix(a, b, t.y);
}

int sky_background_height()
{
  return textureSize(sky_maps, 0).y - SKY_RAY_SIZE.y - SKY_IRR_SIZE.y;
}

/* Radiance seen along d by the camera (full resolution, sun included). */
vec3 sky_background(vec3 d)
{
  int h = sky_background_height();
  return sky_fetch(ivec2(0, 0), ivec2(2 * h, h), d);
}

/* Radiance a GI ray that leaves the scene along d brings (its cone's mean, without the sun). */
vec3 sky_ray(vec3 d)
{
  return sky_fetch(ivec2(0, sky_background_height()), SKY_RAY_SIZE, d);
}

/* Unoccluded irradiance from the sky (without the sun) on a surface of normal n. */
vec3 sky_irradiance(vec3 n)
{
  return sky_fetch(ivec2(0, sky_background_height() + SKY_RAY_SIZE.y), SKY_IRR_SIZE, n);
}
