#version 330 core
// Visibility pass: positions are already in world space per frame, so M is not needed.
layout(location = 0) in vec3 position;
#ifdef TEXCOORD_0_LOC
layout(location = TEXCOORD_0_LOC) in vec2 texcoord_0;
out vec2 uv;
#endif
uniform mat4 P;
uniform mat4 V;

void main()
{
#ifdef TEXCOORD_0_LOC
    uv = texcoord_0;
#endif
    gl_Position = P * V * vec4(position, 1.0);
}
