#version 330 core
// The id pass: the vertex's id colour, times the node's (white) segmentation colour.
uniform vec3 color;
flat in vec3 id_colour;
out vec4 frag_color;

void main()
{
    frag_color = vec4(color * id_colour, 1.0);
}
