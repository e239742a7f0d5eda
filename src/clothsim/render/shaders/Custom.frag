#version 330
// Velvet: fibres standing up from the surface scatter light most at grazing
// angles, so the rim glows and the faces seen head-on stay deep. A woven
// thread pattern from the height map modulates the pile, and a soft
// wrap-around diffuse keeps the folds readable.
uniform vec4 u_color;
uniform vec3 u_cam_pos;
uniform vec3 u_light_pos;
uniform vec3 u_light_intensity;
uniform sampler2D u_texture_2;

in vec4 v_position;
in vec4 v_normal;
in vec2 v_uv;
out vec4 out_color;

void main() {
    vec3 n = normalize(v_normal.xyz);
    if (!gl_FrontFacing) n = -n;
    vec3 to_light = u_light_pos - v_position.xyz;
    vec3 l = normalize(to_light);
    vec3 v = normalize(u_cam_pos - v_position.xyz);
    vec3 radiance = u_light_intensity / dot(to_light, to_light);

    float ndl = dot(n, l);
    float ndv = max(dot(n, v), 0.0);
    float wrap = max((ndl + 0.35) / 1.35, 0.0);
    float rim = pow(1.0 - ndv, 3.0);
    float back = pow(max(dot(-l, v), 0.0), 4.0) * (1.0 - ndv);
    float weave = texture(u_texture_2, v_uv * 4.0).r;

    vec3 base = u_color.rgb * (0.55 + 0.45 * weave);
    vec3 sheen = mix(u_color.rgb, vec3(1.0), 0.55);
    vec3 color = 0.06 * base
               + base * radiance * wrap * 0.9
               + sheen * (rim * 0.8 + back * 0.6) * (0.35 + radiance * max(ndl + 0.5, 0.0));
    // gentle tone curve so the sheen saturates softly
    color = color / (1.0 + 0.3 * color);
    out_color = vec4(pow(color, vec3(0.95)), 1.0);
}
