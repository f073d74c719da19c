#include "shadow_methods.h"

#include <algorithm>
#include <string>

#include "config.h"

namespace penumbra {

const char* passName(PassId pass)
{
    static const char* const names[] = {"camera",         "view_fit",       "view_fit_readback", "shadow_map",  "thin_triangles",
                                        "penumbra_mask",  "afsm_samples",   "afsm_bin",          "afsm_rows",         "afsm_casters",      "rh_build",    "rh_traverse", "classify",    "compact",
                                        "trace",          "shade",          "readback",          "camera_floor", "view_fit_floor",
                                        "shadow_map_floor", "classify_floor", "compact_floor",   "shade_floor"};
    static_assert(sizeof(names) / sizeof(names[0]) == size_t(PassId::Count));
    return pass < PassId::Count ? names[uint32_t(pass)] : "unknown";
}

bool ShadowMethodSpec::uses(Step step) const
{
    for (const std::vector<MethodStep>* steps : {&hard, &softBegin, &softMap, &softEnd})
        if (std::any_of(steps->begin(), steps->end(), [&](const MethodStep& s) { return s.step == step; }))
            return true;
    return false;
}

bool ShadowMethodSpec::softShadows() const { return !softEnd.empty(); }

bool ShadowMethodSpec::drawsAreaMaps() const
{
    return std::any_of(softMap.begin(), softMap.end(), [](const MethodStep& s) { return s.step == Step::ShadowMap; });
}

const std::vector<ShadowMethodSpec>& shadowMethods()
{
    static const std::vector<ShadowMethodSpec> methods = {
        {ShadowMethod::ShadowMap,
         "sm",
         "shadow map",
         {{Step::ShadowMap}, {Step::Shade, kShadeLookup}}, // the lookup in the shade pass: no classify
         {},
         {{Step::ShadowMap}, {Step::Classify, PENUMBRA_SOFT_AVERAGE, PENUMBRA_SOFT_AVERAGE}},
         {{Step::Shade}},
         AreaMapEyes::Strata,
         false},
        {ShadowMethod::Selective,
         "srt",
         "selective ray tracing",
         {{Step::ShadowMap}, {Step::ThinTriangles}, {Step::Classify, PENUMBRA_CLASSIFY_PIP}, {Step::Compact}, {Step::Trace}, {Step::Shade}},
         {{Step::ClearMarks}},
         {{Step::ShadowMap},
          {Step::ThinTriangles},
          {Step::PenumbraMask},
          {Step::Classify, PENUMBRA_SOFT_CENTRE_MASK, PENUMBRA_SOFT_CORNER_MASK}},
         {{Step::Compact}, {Step::Trace}, {Step::Shade}},
         AreaMapEyes::CentreAndRim,
         true},
        {ShadowMethod::FullRayTrace,
         "frt",
         "full ray tracing",
         {{Step::Classify, PENUMBRA_CLASSIFY_ALL}, {Step::Compact}, {Step::Trace}, {Step::Shade}}, // no map: every ray is traced
         {},
         {{Step::Classify, PENUMBRA_SOFT_ALL, PENUMBRA_SOFT_ALL}},
         {{Step::Compact}, {Step::Trace}, {Step::Shade}},
         AreaMapEyes::Centre,
         false,
         true,
         false},
        {ShadowMethod::AliasFree,
         "afsm",
         "alias-free shadow map",
         {{Step::AliasFree}, {Step::AfsmResolve}, {Step::Shade}},
         {},
         {},
         {{Step::AliasFree}, {Step::AfsmResolve}, {Step::Shade}},
         AreaMapEyes::Centre,
         false,
         false},
        {ShadowMethod::RayHierarchy,
         "rh",
         "cone ray hierarchy",
         {{Step::RayHierarchy}, {Step::AfsmResolve}, {Step::Shade}},
         {},
         {},
         {},
         AreaMapEyes::Centre,
         false,
         false},
    };
    return methods;
}

const ShadowMethodSpec& shadowMethodSpec(ShadowMethod method)
{
    for (const ShadowMethodSpec& spec : shadowMethods())
        if (spec.method == method)
            return spec;
    fail("shadows", "unknown shadow method " + std::to_string(int(method)));
}

const char* shadowMethodName(ShadowMethod method)
{
    for (const ShadowMethodSpec& spec : shadowMethods())
        if (spec.method == method)
            return spec.name;
    return "unknown";
}

bool shadowMethodDoesAreaLights(ShadowMethod method) { return shadowMethodSpec(method).softShadows(); }

std::vector<std::string> shadowMethodNames()
{
    std::vector<std::string> names;
    for (const ShadowMethodSpec& spec : shadowMethods())
        names.push_back(spec.name);
    return names;
}

std::string shadowMethodsHelp()
{
    std::string help;
    for (const ShadowMethodSpec& spec : shadowMethods())
        help += (help.empty() ? "" : ", ") + std::string(spec.name) + " (" + spec.description + ")";
    return help;
}

const char* coneTestName(ConeTest test) { return test == ConeTest::Spheres ? "spheres" : "precise"; }

ConeTest parseConeTest(const std::string& name)
{
    if (name == "precise")
        return ConeTest::Precise;
    if (name == "spheres")
        return ConeTest::Spheres;
    fail("--cone-test " + name, "unknown cone test (expected precise or spheres)");
}

const char* rhSortName(RhSort sort) { return sort == RhSort::Off ? "off" : sort == RhSort::On ? "on" : "auto"; }

RhSort parseRhSort(const std::string& name)
{
    for (RhSort sort : {RhSort::Off, RhSort::On, RhSort::Auto})
        if (name == rhSortName(sort))
            return sort;
    fail("--rh-sort " + name, "unknown ray order (expected on, off or auto)");
}

ShadowMethod parseShadowMethod(const std::string& name)
{
    std::string expected;
    const std::vector<ShadowMethodSpec>& methods = shadowMethods();
    for (size_t i = 0; i < methods.size(); ++i) {
        if (name == methods[i].name)
            return methods[i].method;
        expected += (i == 0 ? "" : i + 1 == methods.size() ? " or " : ", ") + std::string(methods[i].name);
    }
    fail("--shadows " + name, "unknown method (expected " + expected + ")");
}

} // namespace penumbra
