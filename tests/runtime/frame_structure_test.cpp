// The frame's structure: push constants checked against the shaders'
// blocks, shadow methods as one table (names, parsing, sequences), and the
// workgroup order the node passes share with C++.
#include <gtest/gtest.h>

#include <vector>

#include "config.h"
#include "passes/classify.h"
#include "passes/gbuffer.h"
#include "passes/penumbra_mask.h"
#include "passes/thin_triangles.h"
#include "passes/trace.h"
#include "pipelines.h"
#include "shadow_methods.h"

namespace penumbra {
namespace {

TEST(FrameStructure, PushConstantsAreReadFromTheShaders)
{
    EXPECT_EQ(vk::shaderPushConstantBytes("classify.comp"), sizeof(passes::ClassifyPush));
    EXPECT_EQ(vk::shaderPushConstantBytes("classify_soft.comp"), sizeof(passes::ClassifySoftPush));
    EXPECT_EQ(vk::shaderPushConstantBytes("penumbra_mask.comp"), sizeof(passes::PenumbraMaskPush));
    EXPECT_EQ(vk::shaderPushConstantBytes("thin_triangles.comp"), sizeof(passes::ThinTrianglesPush));
    EXPECT_EQ(vk::shaderPushConstantBytes("trace.comp"), sizeof(passes::TracePush));
    EXPECT_EQ(vk::shaderPushConstantBytes("shadow_map.vert"), 64u);
    EXPECT_EQ(vk::shaderPushConstantBytes("gbuffer.vert"), sizeof(passes::GBufferPush));
    EXPECT_EQ(vk::shaderPushConstantBytes("gbuffer.frag"), sizeof(passes::GBufferPush));
    EXPECT_NO_THROW(vk::checkPushConstants("classify.comp", 8));
    try {
        vk::checkPushConstants("classify.comp", 12);
        FAIL() << "a 12-byte struct for an 8-byte block was accepted";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("classify.comp: its push constants are 8 bytes, the pass pushes 12"), std::string::npos)
            << e.what();
    }
    EXPECT_THROW(vk::shaderPushConstantBytes("no_such_shader.comp"), Error);
}

// config.h's interleavedChunk, the same source the shaders compile: every chunk
// of a dispatch goes to exactly one workgroup, and a contiguous share of the
// workgroups (what one lavapipe thread runs) reaches across the chunks.
TEST(FrameStructure, InterleavedChunksCoverEveryChunkOnce)
{
    for (uint32_t chunks = 1; chunks <= 2000; ++chunks) {
        std::vector<int> seen(chunks, 0);
        for (uint32_t group = 0; group < chunks; ++group) {
            const uint32_t chunk = gpu::interleavedChunk(group, chunks);
            ASSERT_LT(chunk, chunks) << "group " << group << " of " << chunks;
            ++seen[chunk];
        }
        for (uint32_t chunk = 0; chunk < chunks; ++chunk)
            ASSERT_EQ(seen[chunk], 1) << "chunk " << chunk << " of " << chunks;
        if (chunks < 2 * PENUMBRA_GROUP_INTERLEAVE)
            continue;
        // Two threads, each with a stripe's worth of groups or more: each half of the groups takes
        // chunks from both halves of the range.
        for (uint32_t half = 0; half < 2; ++half) {
            uint32_t low = 0, high = 0;
            for (uint32_t group = half * (chunks / 2); group < (half + 1) * (chunks / 2); ++group)
                (gpu::interleavedChunk(group, chunks) < chunks / 2 ? low : high)++;
            EXPECT_GT(low, 0u) << chunks;
            EXPECT_GT(high, 0u) << chunks;
        }
    }
    EXPECT_EQ(gpu::interleavedChunk(5, 10), 5u); // at most PENUMBRA_GROUP_INTERLEAVE chunks: in order
    EXPECT_EQ(gpu::interleavedChunk(1, 35), 3u); // 35 chunks: stripes of 3, 3, 3 and then of 2
    EXPECT_EQ(gpu::interleavedChunk(16, 35), 1u);
    EXPECT_EQ(gpu::interleavedChunk(40, 35), 40u); // past the chunks: no chunk's work
}

TEST(FrameStructure, ShadowMethodsComeFromOneTable)
{
    const std::vector<std::string> names = shadowMethodNames();
    ASSERT_EQ(names.size(), shadowMethods().size());
    for (const ShadowMethodSpec& spec : shadowMethods()) {
        EXPECT_EQ(parseShadowMethod(spec.name), spec.method);
        EXPECT_STREQ(shadowMethodName(spec.method), spec.name);
        EXPECT_EQ(&shadowMethodSpec(spec.method), &spec);
        EXPECT_NE(shadowMethodsHelp().find(std::string(spec.name) + " (" + spec.description + ")"), std::string::npos);
        // Every sequence shades each light once, last.
        ASSERT_FALSE(spec.hard.empty());
        EXPECT_EQ(spec.hard.back().step, Step::Shade) << spec.name;
        if (spec.softShadows()) {
            EXPECT_EQ(spec.softEnd.back().step, Step::Shade) << spec.name;
        }
    }
    try {
        parseShadowMethod("pcss");
        FAIL() << "an unknown method was accepted";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("unknown method (expected sm, srt, frt, afsm or rh)"), std::string::npos) << e.what();
    }
    EXPECT_TRUE(shadowMethodSpec(ShadowMethod::Selective).traces());
    EXPECT_FALSE(shadowMethodSpec(ShadowMethod::ShadowMap).traces());
    EXPECT_FALSE(shadowMethodSpec(ShadowMethod::FullRayTrace).drawsAreaMaps());
    EXPECT_STREQ(passName(PassId::ThinTriangles), "thin_triangles");
}

} // namespace
} // namespace penumbra
