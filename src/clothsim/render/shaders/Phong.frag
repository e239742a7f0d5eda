#version 330
// Blinn-Phong: ambient + diffuse + specular, each weight a uniform so that
// every term can be shown on its own.
uniform vec4 u_color;
uniform vec3 u_cam_pos;
uniform vec3 u_light_pos;
uniform vec3 u_light_intensity;
uniform float u_ka;
uniform float u_kd;
uniform float u_ks;
uniform float u_p;

in vec4 v_position;
in vec4 v_normal;
out vec4 out_color;

void main() {
    vec3 n = normalize(v_normal.xyz);
    if (!gl_FrontFacing) n = -n;
    vec3 to_light = u_light_pos - v_position.xyz;
    float r2 = dot(to_light, to_light);
    vec3 l = normalize(to_light);
    vec3 v = normalize(u_cam_pos - v_position.xyz);
    vec3 h = normalize(l + v);
    vec3 radiance = u_light_intensity / r2;
    vec3 ambient = u_ka * u_color.rgb;
    vec3 diffuse = u_kd * u_color.rgb * radiance * max(dot(n, l), 0.0);
    vec3 specular = u_ks * radiance * pow(max(dot(n, h), 0.0), u_p);
    out_color = vec4(ambient + diffuse + specular, 1.0);
}
