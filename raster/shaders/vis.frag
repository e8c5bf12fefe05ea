#version 330 core
// Writes (object id, triangle id) of the single sample of each pixel; no colour is rasterised.
uniform uint object_id;
#ifdef TEXCOORD_0_LOC
in vec2 uv;
uniform sampler2D alpha_tex;   // single channel, nearest texel, same lookup as shading/surface.py
uniform ivec2 alpha_size;
uniform float alpha_threshold;
#endif
out uvec2 ids;

void main()
{
#ifdef TEXCOORD_0_LOC
    vec2 f = uv - floor(uv);
    ivec2 texel = min(ivec2(f * vec2(alpha_size)), alpha_size - 1);
    if (texelFetch(alpha_tex, texel, 0).r < alpha_threshold) discard;
#endif
    ids = uvec2(object_id, uint(gl_PrimitiveID));
}
