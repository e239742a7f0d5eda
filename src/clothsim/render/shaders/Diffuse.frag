#version 330
// Lambert shading under a point light whose power falls off with distance squared.
uniform vec4 u_color;
uniform vec3 u_light_pos;
uniform vec3 u_light_intensity;

in vec4 v_position;
in vec4 v_normal;
out vec4 out_color;

void main() {
    vec3 n = normalize(v_normal.xyz);
    if (!gl_FrontFacing) n = -n;
    vec3 to_light = u_light_pos - v_position.xyz;
    float r2 = dot(to_light, to_light);
    float lambert = max(dot(n, normalize(to_light)), 0.0);
    vec3 radiance = u_light_intensity / r2;
    out_color = vec4(u_color.rgb * radiance * lambert, 1.0);
}
