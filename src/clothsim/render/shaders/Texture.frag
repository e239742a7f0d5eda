#version 330
// The colour texture looked up at the uv, lit like Diffuse with a touch of ambient.
uniform sampler2D u_texture_1;
uniform vec3 u_light_pos;
uniform vec3 u_light_intensity;

in vec4 v_position;
in vec4 v_normal;
in vec2 v_uv;
out vec4 out_color;

void main() {
    vec3 n = normalize(v_normal.xyz);
    if (!gl_FrontFacing) n = -n;
    vec3 to_light = u_light_pos - v_position.xyz;
    vec3 albedo = texture(u_texture_1, v_uv).rgb;
    float lambert = max(dot(n, normalize(to_light)), 0.0);
    vec3 radiance = u_light_intensity / dot(to_light, to_light);
    out_color = vec4(albedo * (0.25 + radiance * lambert), 1.0);
}
