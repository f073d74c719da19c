// Penumbra public C++ API: load a model, set camera and lights, choose a
// shadow method, render headless with Vulkan to an image in memory or a file,
// and read per-pass statistics. The penumbra CLI is built on this API only.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "penumbra/error.h"
#include "penumbra/io.h"
#include "penumbra/mesh.h"
#include "penumbra/model_format.h"
#include "penumbra/scene_file.h"

namespace penumbra {

// How hard shadows are computed (Lauterbach et al. 2009, section 3.1):
// sm: the shadow map alone; srt: the shadow map, with rays for the pixels
// classified as potentially incorrect (depth discontinuities that may affect
// the pixel, thin triangles rasterized conservatively); frt: a ray for every
// light-facing pixel. srt and frt use the same GPU ray tracer over the
// shared BVH.
//
// Area lights (rectangle, disk, sphere) cast soft shadows (section 3.2): sm
// averages K point-light shadow maps over the light; srt traces light samples
// only for the pixels in the penumbra mask (edges of a shadow map from the
// light's centre, and optionally its corners, splatted with the light's
// projected shape) and takes umbra or lit from the centre's shadow map
// elsewhere; frt traces the samples for every pixel. srt and frt use the same
// stratified samples, seeded by the pixel (penumbra/light_sampling.h).
// afsm: alias-free shadow maps (Sintorn et al. 2008, section 3): the camera's
// samples binned in the light's view, every caster rasterized conservatively
// over them and tested exactly per sample; hard shadows only for now.
// rh: cone ray hierarchies (Olsson and Assarsson 2011): the shadow rays of
// point and spot lights bounded by a 4-way tree of cones from the light, which
// the casters traverse breadth-first down to exact ray/triangle tests; no
// map, no projection plane (a point light's cube faces only split the rays).
enum class ShadowMethod { ShadowMap, Selective, FullRayTrace, AliasFree, RayHierarchy };

// rh: how a triangle is tested against a cone of rays.
enum class ConeTest {
    Precise, // Olsson and Assarsson 2011, section 3.2: edge and tangent planes through the apex, the supporting plane's range
    Spheres, // the triangle's bounding sphere (Roger et al. 2007), for comparison
};
const char* coneTestName(ConeTest test);
ConeTest parseConeTest(const std::string& name); // throws Error

// rh: the order of the rays before the hierarchy is built (section 3.5).
enum class RhSort {
    Off,  // by pixel (8x8 tiles in Morton order): the screen-space hierarchy
    On,   // by direction from the light (a Hilbert curve over each layer)
    Auto, // per layer and frame, by the screen-space coherence the GPU measures (README, rh)
};
const char* rhSortName(RhSort sort);
RhSort parseRhSort(const std::string& name); // throws Error

const char* shadowMethodName(ShadowMethod method);
ShadowMethod parseShadowMethod(const std::string& name); // throws Error
std::vector<std::string> shadowMethodNames();           // every method's name, in enum order
std::string shadowMethodsHelp();                        // "sm (shadow map), srt (selective ray tracing), ..."
bool shadowMethodDoesAreaLights(ShadowMethod method);   // soft shadows from area lights

// Culling of the camera and shadow-map raster passes with the top of the
// shared BVH (Lauterbach et al. 2009, section 5.1): none draws every cluster;
// frustum drops clusters outside each view's frustum; all also drops clusters
// hidden behind what the view drew last frame (two-phase occlusion queries).
// The image is bit-identical in every mode; the ray tracer always sees the
// whole BVH.
enum class CullMode { None, Frustum, All };

const char* cullModeName(CullMode mode);
CullMode parseCullMode(const std::string& name); // throws Error

struct DeviceInfo {
    uint32_t index = 0;          // position in vkEnumeratePhysicalDevices
    std::string name;            // e.g. "llvmpipe (LLVM 15.0.6, 256 bits)"
    std::string type;            // "discrete", "integrated", "virtual", "cpu", "other"
    std::string driver;          // driver name and version, e.g. "llvmpipe Mesa 22.3.6"
    std::string apiVersion;      // e.g. "1.3.230"
};

// How the raster passes (camera, shadow maps, afsm and rh casters) index the
// compressed model's triangles. The tracer always reads the file's strips.
//   Strips:    the file's 8-bit strips with primitive restart, drawn in place
//              (no copy; what GPUs do best).
//   Triangles: an 8-bit triangle list per cluster, decoded from the strips at
//              load (3 more bytes per triangle on the device). lavapipe splits
//              a draw at every restart and runs its vertex pipeline once per
//              strip: on a 10.9 M-triangle model the lists cut the raster
//              passes' CPU time by a quarter and its page faults 3-10x.
//   Auto:      Triangles on a CPU device (lavapipe), Strips on a GPU.
// The images are the same bit for bit with either (same triangles, same
// order, same vertex order).
enum class RasterIndices { Auto, Strips, Triangles };

const char* rasterIndicesName(RasterIndices indices);
RasterIndices parseRasterIndices(const std::string& name); // throws Error

struct RendererOptions {
    // Empty: the first discrete GPU, else integrated, else any other device
    // (lavapipe). Otherwise a device index or a case-insensitive substring of its name.
    std::string device;
    // Enables VK_LAYER_KHRONOS_validation; every message is printed to stderr
    // and counted (validationMessageCount). Also on when the environment
    // variable PENUMBRA_VALIDATION=1 is set.
    bool validation = false;
    // Largest model buffer in bytes (0: min(1 GiB, maxMemoryAllocationSize)).
    // Larger models are split into chunks; tests set it small to exercise that.
    uint64_t maxModelBufferBytes = 0;
    // What the raster passes draw (RasterIndices above).
    RasterIndices rasterIndices = RasterIndices::Auto;
    // Longest wait for the device to finish one submission (a frame's passes
    // up to a read-back, an upload). A longer one fails with one line,
    // "device did not finish <passes> in N s", and the renderer refuses further
    // work. The environment variable PENUMBRA_DEVICE_TIMEOUT (seconds) overrides it.
    double deviceTimeoutSeconds = 300.0;
    // Out of core (runtime/README.md, "Geometry budget"): at most this many
    // bytes of cluster geometry (vertices, strips, raster triangle lists) on
    // the device, in pages of geometryPageBytes; the BVH nodes and the
    // cluster table stay resident besides. 0: the whole model in core.
    // Pages are uploaded as the frame's views and rays need them; the image
    // is the same bit for bit as without a budget. A budget smaller than one
    // view's working set fails the frame with one line.
    uint64_t geometryBudgetBytes = 0;
    uint64_t geometryPageBytes = 768 * 1024; // a multiple of 48 bytes (3 KiB .. 1 GiB)
};

struct RenderSettings {
    uint32_t width = 1024;
    uint32_t height = 1024;
    ShadowMethod shadows = ShadowMethod::ShadowMap;
    uint32_t shadowMapSize = 2048;      // texels per side (per cube face for point lights)
    float depthBiasConstant = 1.0f;     // vkCmdSetDepthBias constant factor (units of minimum resolvable depth)
    float depthBiasSlope = 1.5f;        // vkCmdSetDepthBias slope factor
    float ambient = 0.15f;              // ambient term, fraction of albedo
    float albedo = 0.8f;                // grey surface reflectance
    bool colors = true;                 // times the model's material colours (off: every surface grey, as before them)
    float background[3] = {0.06f, 0.07f, 0.09f};
    bool readbackGBuffer = false;       // also return world positions and light-0 visibility
    bool readbackLightLayers = false;   // also return every light's visibility and the traced pixels (Frame::lightVisibility, pip)
    bool debugPip = false;              // tint the pixels given rays red (the paper's Figure 4)
    // Shadow-ray origins move this far along the light-facing normal (model
    // units); 0: shadowRayOffset of the model.
    float rayOffset = 0.0f;
    // Soft shadows (area lights).
    uint32_t lightSamples = 16;         // srt/frt: light samples per pixel, 4..256
    uint32_t penumbraMaps = 1;          // srt: shadow maps whose masks mark the penumbra: 1 (centre) or 5 (centre and corners)
    uint32_t softShadowMaps = 4;        // sm: point-light shadow maps averaged over the light, 1..6
    CullMode cull = CullMode::All;      // culling of the camera and shadow-map raster passes
    ConeTest coneTest = ConeTest::Precise; // rh: the cone/triangle test
    RhSort rhSort = RhSort::Auto;          // rh: the rays ordered by direction (section 3.5), by pixel, or chosen per frame
    bool rhTwoPass = false;                // rh: large casters first, then the hierarchy rebuilt without the rays they shadowed (3.4)
    bool rhEarlyAccept = true;             // rh: a cone a triangle covers shadows its rays without descending (3.3)
    // rh: clusters marked closed cast only light-back-facing triangles (3.6); off by default: a receiver
    // within one ray offset of a closed surface may start its ray inside it and lose its shadow (README, rh).
    bool rhClosedMeshes = false;
    bool rhCullBehindReceivers = true;     // rh: casters deeper than every receiver they could shadow left out (exact; README, rh)
    // Fit the shadow maps of directional and area lights to what the camera
    // sees (the G-buffer's bounds in each map, read back before the shadow
    // pass) instead of the whole model: finer texels, and frustum culling
    // drops the casters that cannot shadow a visible pixel (area lights, srt:
    // the map is widened by the angle at which a penumbra can still reach
    // them). The image depends only on the camera and lights, never on
    // culling or earlier frames. Point and spot lights keep their maps.
    bool fitShadowMapsToView = true;
    // CullMode Frustum and All: the shadow maps of directional, point and spot
    // lights also cull the casters whose footprint in the map holds no point
    // the camera sees (a grid of those points per map layer, read back with
    // the fit: one host round trip per frame). Same image either way.
    bool cullBesideReceivers = true;
    // CullMode::All: a view whose occlusion queries cull little goes frustum-only
    // for a few frames, and a view whose frustum holds fewer than
    // PENUMBRA_CULL_MIN_TRIANGLES (65536) triangles is culled by its frustum
    // only. false (tests): queries in every view, every frame.
    bool adaptiveOcclusion = true;
    // srt: a frame traces every light-facing pixel (frt's sequence: no shadow
    // map, no classification) where that measured cheaper on this renderer.
    // The first frames run srt's own sequence; once they are steady two frames
    // trace every pixel (probes, the first not timed); then each frame takes the way with the lower
    // GPU time, the other one probed again 8 frames later (twice as many after
    // each further probe that loses, at most 256). Both ways are exact where they
    // trace; every-pixel frames are the oracle's image, srt's differ from it on
    // the few pixels its classification gets wrong. Frames with measureFloors,
    // debugPip or readbackLightLayers, and paged geometry, always run srt's own
    // sequence. FrameStats::srtTracedAll says which way a frame took. false:
    // always srt's own sequence.
    bool srtTraceAllWhenCheaper = true;
    // Benchmarks (penumbra bench's floor table): also time each pass's floor
    // in the frame, recorded just before the pass as "<pass>_floor": for
    // view_fit, classify, compact and shade a null twin with the same
    // bindings that reads every input once per pixel and writes the outputs
    // (shaders/floor.glsli); for camera and shadow_map every triangle of the
    // model drawn uncompressed, depth only. The image is unchanged; the frame
    // takes longer. Needs a model loaded with loadModel.
    bool measureFloors = false;
};

// Linear-light RGBA float image, row-major, top row first.
struct Image {
    uint32_t width = 0;
    uint32_t height = 0;
    std::vector<float> rgba;
};

struct PassTiming {
    std::string name;   // "camera", "shadow_map", "shade", ...
    double gpuMs = 0;   // from timestamp queries
};

// Culling of one raster view: "camera", "light0", or "light0.face3" for the
// cube faces of a point light's shadow map.
struct ViewCullStats {
    std::string name;
    uint64_t nodesTested = 0;      // BVH top-level and cluster nodes tested against the frustum
    uint64_t clustersDrawn = 0;    // clusters drawn in the view's final pass
    uint64_t clustersCulled = 0;   // clusters of the model not drawn
    uint64_t clustersOccluded = 0; // of those, the ones in the frustum culled by occlusion queries
    uint64_t clustersBesideReceivers = 0; // of those, shadow views: the ones in the frustum that can shadow no visible point
    uint64_t trianglesDrawn = 0;
    uint64_t trianglesCulled = 0;
    uint64_t queriesIssued = 0;    // occlusion queries (node/cluster boxes)
    double cpuMs = 0;              // CPU time planning the view (traversal, draw lists, query boxes)
    double gpuMs = 0;              // GPU time of the view's raster pass: both phases, queries, predicate pass
};

struct FrameStats {
    uint64_t triangles = 0;
    uint32_t width = 0, height = 0;
    uint32_t lights = 0;
    ShadowMethod shadows = ShadowMethod::ShadowMap;
    uint64_t coveredPixels = 0;   // pixels showing the model
    uint64_t pipPixels = 0;       // pixels given rays (summed over lights): PIP in srt, light-facing in frt
    double pipFraction = 0;       // pipPixels / (coveredPixels * lights)
    uint64_t rays = 0;            // shadow rays traced
    uint64_t nodesVisited = 0;    // BVH nodes tested by the tracer
    uint64_t leavesVisited = 0;   // strip-range leaves tested
    uint64_t triangleTests = 0;   // ray/triangle tests
    // srt (RenderSettings::srtTraceAllWhenCheaper): this frame traced every
    // light-facing pixel; it was a probe of the way not chosen; both ways have
    // been measured (the choice is made).
    bool srtTracedAll = false;
    bool srtProbe = false;
    bool srtChosen = false;
    // rh: casters sent through the hierarchies, batches of them, submissions
    // of traversal steps, and the most (triangle, node) pair memory in use at once.
    uint64_t rhCasters = 0;
    uint32_t rhBatches = 0, rhRounds = 0;
    uint64_t rhPeakPairBytes = 0;
    // afsm: clusters of the model flagged closed (kClusterClosed), and how they
    // cast this frame: "back faces" (the paper's light-back-facing triangles
    // only), "both sides (camera inside a closed mesh)" (the rays of what it
    // sees leave through front faces), "both sides (ray offset above the
    // default)" (RenderSettings::rayOffset larger than the offset the
    // preprocessor kept flagged solids clear of: a ray could start inside
    // one), "none closed"; open clusters cast both sides, with the tracer's
    // ray offset (rayOffset) as the only epsilon.
    uint64_t afsmClosedClusters = 0;
    std::string afsmClosedCasting;
    // afsm: the most view samples listed in one grid cell of any layer, and
    // the extra draws of the casters over crowded cells (one per slice of a
    // cell's list past the first; a fragment tests at most
    // passes::afsmSliceSamples of a cell's samples: lavapipe ends a shader
    // invocation's loops after 65535 iterations).
    uint32_t afsmCellMost = 0;
    uint32_t afsmSliceDraws = 0;
    // afsm, hard shadows: the casters the compute path left to the compute
    // pass that tests them a grid row at a time (afsm_wide.comp), and the
    // light layers whose raster path still drew because that pass left some
    // clusters to it (its list full, or a caster past its loop budget).
    uint32_t afsmWideCasters = 0;
    uint32_t afsmWideRasterLayers = 0;
    // afsm, a directional light's hard shadows: the layers whose casters went
    // in two passes (those nearest the light first: PENUMBRA_AFSM_NEAR_DEPTH),
    // and of those, the layers whose second pass went after the cells' depths
    // were counted again over the samples still lit (the first pass shadowed
    // at least PENUMBRA_AFSM_REFRESH_SHARE of the pixels).
    uint32_t afsmTwoPassLayers = 0;
    uint32_t afsmRefreshedLayers = 0;
    // afsm: whether the small casters were binned in compute (afsm_bin.comp):
    // not when the model's largest leaf could take one invocation past that
    // loop limit (passes::afsmBinIterations), nor for the uncompressed model;
    // then the raster path takes every caster.
    bool afsmComputePath = false;
    uint32_t rhLights = 0, rhSortedLights = 0; // hierarchies built (one per light), and those over rays sorted by direction
    uint64_t rhAcceptedNodes = 0;              // nodes found covered by a triangle and accepted whole (early accept, section 3.3)
    double rhIncoherence = 0;                  // --rh-sort auto: the last light's measured screen-space incoherence (README, rh)
    uint32_t rhClosedCulled = 0;               // lights whose closed clusters cast only light-back-facing triangles (3.6)
    // Geometry budget (RendererOptions::geometryBudgetBytes; all 0 without one).
    uint64_t geometryBudgetBytes = 0;   // the pool: whole pages within the budget
    uint64_t geometryBytes = 0;         // every page's contents (the model's paged geometry)
    uint64_t residentPeakBytes = 0;     // most pages resident at once this frame, in bytes
    uint64_t modelDeviceBytes = 0;      // all of the model on the device: the pool and what stays resident (Renderer::modelDeviceBytes)
    uint64_t pagesUploaded = 0;         // this frame
    uint64_t bytesStreamed = 0;         // page contents uploaded this frame
    uint32_t parkingRounds = 0;         // dispatches that traced parked rays again
    uint64_t parkedRays = 0;            // rays (pixel entries) parked, summed over the rounds
    uint64_t penumbraPixels = 0;  // pixels whose visibility of an area light is strictly between 0 and 1 (summed over lights)
    double penumbraFraction = 0;  // penumbraPixels / (coveredPixels * area lights)
    uint32_t lightSamples = 0;    // samples per pixel of area lights (0: no area light)
    float rayOffset = 0;          // shadow-ray origin offset used
    DeviceInfo device;
    std::vector<PassTiming> passes;
    CullMode cull = CullMode::None;
    std::vector<ViewCullStats> views; // per raster view; empty for the uncompressed reference
    double gpuMs = 0;       // first to last timestamp
    double cpuMs = 0;       // record + submit + wait + readback, wall clock
};

struct Frame {
    Image color;
    // With RenderSettings::readbackGBuffer: per pixel world position (xyz, w = 1
    // when covered, 0 for background), the face normal turned toward the
    // camera (xyz, as every pass reads it: stored octahedral, 16 bits a
    // coordinate, about 3e-5 from the exact one; w = the material colour the
    // frame shows, linear 8-bit r | g << 8 | b << 16, 16777215 for white, and
    // white everywhere when RenderSettings::colors is off) and visibility of
    // light 0 (1 lit, 0 shadowed, -1 background).
    std::vector<float> positions;
    std::vector<float> normals;
    std::vector<float> visibility;
    // With RenderSettings::readbackLightLayers: the visibility of light i at
    // [i * pixels, (i + 1) * pixels), as above; and per pixel 1 where some
    // light gave it rays (srt's PIP pixels, frt's light-facing ones), else 0.
    std::vector<float> lightVisibility;
    std::vector<float> pip;
    FrameStats stats;
};

// Shadow-ray origin offset for a model: max(1e-5 x its bounds diagonal,
// 4 x its largest quantization error). The oracle uses the same value.
float shadowRayOffset(const Bounds& bounds, float maxPositionError);

// Validation-layer messages seen by every Renderer of this process so far.
uint32_t validationMessagesInProcess();

// Lists the Vulkan devices the loader reports (throws Error without Vulkan).
std::vector<DeviceInfo> listDevices();

class Renderer {
public:
    explicit Renderer(const RendererOptions& options = {});
    ~Renderer();
    Renderer(const Renderer&) = delete;
    Renderer& operator=(const Renderer&) = delete;

    const DeviceInfo& device() const;

    // Uploads a compressed model (a .penumbra file from openModelFile, or
    // buildCompressedModel's result) once and draws straight from it: 8-bit
    // strips, 16-bit quantized vertices, no uncompressed copy on the device.
    // Replaces any previous model.
    void loadModel(const CompressedModel& model);
    // Preprocesses the mesh in memory with default options, then loadModel.
    void loadModel(const Mesh& mesh);
    // Benchmarks only: uploads an indexed float triangle list and draws that
    // instead, so raster time can be compared against the compressed form.
    void loadUncompressedReference(const Mesh& mesh);
    // Bytes of device memory the loaded model occupies.
    uint64_t modelDeviceBytes() const;
    // Tests only: draws the loaded compressed model exactly as the raster
    // passes do, with the rasterizer discarded, and returns every vertex's
    // position as decoded by the vertex shader (xyz per vertex; NaN where no
    // strip references the vertex).
    std::vector<float> decodeVerticesOnGpu();
    // Camera and lights; without setCamera, a camera framing the model is used;
    // without lights, a directional sun. At most 8 lights.
    void setCamera(const Camera& camera);
    void setLights(const std::vector<Light>& lights);

    Frame render(const RenderSettings& settings);

    // Number of validation-layer messages seen so far (0 unless validation is on).
    uint32_t validationMessageCount() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl;
};

// Camera looking at the model from above and to the side (from +x, +y, +z).
Camera defaultCamera(const Bounds& bounds);
// Directional sun from above, over the default camera's left shoulder, so a
// model framed by defaultCamera shows its own cast shadow (on itself and on a
// ground) beside and behind it.
Light defaultLight();

// Tone curve of 8-bit outputs (PNG, JPEG, ...): none clamps the exposed
// linear value to [0, 1]; filmic is Krzysztof Narkowicz's fit of the ACES
// reference rendering transform ("ACES Filmic Tone Mapping Curve", 2015):
// (x (2.51 x + 0.03)) / (x (2.43 x + 0.59) + 0.14), per channel, then sRGB.
enum class ToneMap { None, Filmic };

const char* toneMapName(ToneMap curve);
ToneMap parseToneMap(const std::string& name); // throws Error
// The curve alone (linear in, display-linear out in [0, 1], before sRGB).
float applyToneMap(float value, ToneMap curve);

// A named float channel written after R, G, B, A to an OpenEXR file, full
// (32-bit) precision: e.g. "visibility.light0", "pip", "Z". width x height
// values, top row first.
struct ImageLayer {
    std::string name;
    std::vector<float> values;
};

// How writeImage turns the linear frame into a file. The defaults write the
// linear values unchanged (what writeImage has always written); the CLI
// defaults to --exposure auto --tonemap filmic.
struct ImageOptions {
    // 8-bit outputs only: the linear RGB is multiplied by exposure, then the
    // tone curve and sRGB encoding are applied. Float outputs (.exr, .hdr,
    // .tif) keep the renderer's linear values.
    float exposure = 1.0f;
    ToneMap tonemap = ToneMap::None;
    // .exr only: extra float channels (each width x height values).
    std::vector<ImageLayer> layers;
};

// The automatic exposure: the 95th percentile of the luminance
// (0.2126 R + 0.7152 G + 0.0722 B) of the covered pixels (those whose colour
// is not exactly the background's) maps to 0.8 after the curve. 1 when no
// pixel is covered or the percentile is 0.
float autoExposure(const Image& image, ToneMap curve, const float background[3]);

// Writes a PNG (8-bit sRGB), EXR (half float linear) or any other format
// OpenImageIO knows by extension; to a temporary name, then renamed.
void writeImage(const Image& image, const std::string& path);
void writeImage(const Image& image, const std::string& path, const ImageOptions& options);

// Layers of a frame rendered with RenderSettings::readbackGBuffer, for
// ImageOptions::layers: "visibility.light0" (Frame::visibility: 1 lit, 0
// shadowed, in between in a penumbra, -1 background), "Z" (depth along the
// camera's view axis, model units; +infinity for the background) and, when
// pip is not empty, "pip" (1 for the pixels given rays, else 0). With
// RenderSettings::readbackLightLayers too: "visibility.lightN" for every
// light, and "pip" from Frame::pip when the argument is empty.
std::vector<ImageLayer> frameLayers(const Frame& frame, const Camera& camera, const std::vector<float>& pip = {});
// The pixels a debugPip render tinted: 1 where the two frames' colours
// differ (same scene, settings differing only in debugPip), else 0.
std::vector<float> pipMask(const Image& plain, const Image& tinted);

// Ground plane (real geometry: it casts and receives like the model).
// Rule for --ground auto: a single object gets a ground; a scene, or an
// object already standing on its own floor, does not. The mesh counts as a
// single object when its height (y extent) is at least a quarter of its
// larger horizontal extent (wide, flat bounds, a city, a floor plan, a site,
// are taken to hold their own ground), and it does not stand on its own
// floor: the vertices above its lowest 2% of height cover at least half of
// its bounds' horizontal area (a rock scanned on a wide plate does not).
bool wantsGround(const Mesh& mesh);
// Just below the model's lowest point: min.y - 0.002 x the bounds diagonal.
float groundHeight(const Bounds& modelBounds);
// Appends a square at height y, centred under the model, reaching
// max(horizontal extents) + 3 x the height beyond the bounds on each side
// (the shadow of a sun 20 degrees above the horizon), as 8 x 8 quads facing +y.
void addGround(Mesh& mesh, const Bounds& modelBounds, float y);
// A --ground choice: auto (wantsGround decides; not for compressed models,
// which are drawn as stored), below (always, at groundHeight), off, or y=VALUE.
struct Ground {
    enum class Kind { Auto, Below, Off, At } kind = Kind::Off;
    float y = 0.0f; // Kind::At
};
Ground parseGround(const std::string& text); // "auto", "below", "off", "y=VALUE"; throws Error
// Adds the ground the choice asks for, for a model with these bounds, to mesh.
// A compressed model (clusters not empty) is first decoded into mesh and
// cleared, so the caller preprocesses mesh again. Returns whether it added one.
bool applyGround(const Ground& ground, const Bounds& modelBounds, Mesh& mesh, CompressedModel& compressed);
// Every triangle of a compressed model, decoded (positions as the GPU decodes
// them), so a ground can be added and the model rebuilt.
Mesh decodeMesh(const CompressedModel& model);
// Throws Error when writeImage could not write this path's format.
void checkImagePath(const std::string& path);

// Summary line: "triangles 1234567 | 1024x1024 | llvmpipe ... | camera 3.1 ms | ..."
std::string summaryLine(const FrameStats& stats);
// Stats as JSON text (device name and driver included).
std::string statsJson(const FrameStats& stats);

} // namespace penumbra
