// The frame's structure: push constants checked against the shaders'
// blocks, and shadow methods as one table (names, parsing, sequences).
#include <gtest/gtest.h>

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
