#version 330 core
// The id pass: the clip position as pyrender's segmentation pass computes it, and each
// vertex's id colour (color_0) passed on uninterpolated.
layout(location = 0) in vec3 position;
layout(location = COLOR_0_LOC) in vec4 color_0;
layout(location = INST_M_LOC) in mat4 inst_m;

uniform mat4 P;
uniform mat4 V;
uniform mat4 M;

flat out vec3 id_colour;

void main()
{
    mat4 light_matrix = P * V;
    gl_Position = light_matrix * M * inst_m * vec4(position, 1.0);
    id_colour = color_0.rgb;
}
