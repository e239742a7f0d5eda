#version 330
// Shading of displaced geometry: the height map also tilts the normal,
// as in Bump, so fine detail shows where the mesh is too coarse to carry it.
uniform vec4 u_color;
uniform vec3 u_cam_pos;
uniform vec3 u_light_pos;
uniform vec3 u_light_intensity;
uniform sampler2D u_texture_2;
uniform vec2 u_texture_2_size;
uniform float u_normal_scaling;
uniform float u_height_scaling;

in vec4 v_position;
in vec4 v_normal;
in vec4 v_tangent;
in vec2 v_uv;
out vec4 out_color;

float height_at(vec2 uv) {
    return texture(u_texture_2, uv).r;
}

void main() {
    vec3 n = normalize(v_normal.xyz);
    if (!gl_FrontFacing) n = -n;
    vec3 t = v_tangent.xyz - dot(v_tangent.xyz, n) * n;
    t = length(t) > 1e-6 ? normalize(t) : normalize(cross(n, abs(n.y) < 0.9 ? vec3(0, 1, 0) : vec3(1, 0, 0)));
    vec3 b = cross(n, t);
    vec2 texel = 1.0 / u_texture_2_size;
    float h = height_at(v_uv);
    float du = (height_at(v_uv + vec2(texel.x, 0.0)) - h) * u_height_scaling * u_normal_scaling;
    float dv = (height_at(v_uv + vec2(0.0, texel.y)) - h) * u_height_scaling * u_normal_scaling;
    vec3 nd = normalize(mat3(t, b, n) * vec3(-du, -dv, 1.0));

    vec3 to_light = u_light_pos - v_position.xyz;
    vec3 l = normalize(to_light);
    vec3 v = normalize(u_cam_pos - v_position.xyz);
    vec3 hv = normalize(l + v);
    vec3 radiance = u_light_intensity / dot(to_light, to_light);
    vec3 color = 0.1 * u_color.rgb
               + u_color.rgb * radiance * max(dot(nd, l), 0.0)
               + 0.5 * radiance * pow(max(dot(nd, hv), 0.0), 64.0);
    out_color = vec4(color, 1.0);
}
