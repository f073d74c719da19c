#version 450
// Thin-triangle pass: the nearest depth of a thin triangle over this texel
// (the attachment blends with MIN; cleared to 1 = nothing thin here). Draws
// the rectangles of thin_detect.comp.glsl through thin_quads.vert.glsl.

layout(location = 0) in float nearestDepth;
layout(location = 0) out float outDepth;

void main()
{
    outDepth = nearestDepth;
}
