#version 460
// Miss shader of the gather hit-group test: a point query that met no box keeps the zero
// sums the ray generation set, so there is nothing to do (the pipeline still needs a miss
// group for miss index 0).
#extension GL_EXT_ray_tracing : require
#include "gather_payload.glsl"

layout(location = 0) rayPayloadInEXT ArpaGatherPayload payload;

void main() {
}
