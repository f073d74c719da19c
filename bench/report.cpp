// The suite's results folder: CSV and JSON records, gnuplot data and scripts,
// PNG plots, side-by-side images and summary.md (file list: README.md,
// section Benchmarks).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "suite_internal.h"

namespace penumbra::bench {

namespace {

namespace fs = std::filesystem;

// Columns of the data files: the methods in this order (afsm last, so that older columns keep their numbers).
constexpr const char* kMethodOrder[] = {"sm", "srt", "frt", "oracle", "afsm"};
constexpr const char* kSoftMethodOrder[] = {"sm", "srt", "frt", "oracle", "afsm"};

void writeFile(const fs::path& path, const std::string& text)
{
    fs::path temporary = path;
    temporary += ".tmp";
    {
        std::ofstream out(temporary, std::ios::binary);
        out << text;
        if (!out.flush())
            fail(path.string(), "cannot write");
    }
    std::error_code error;
    fs::rename(temporary, path, error);
    if (error)
        fail(path.string(), "cannot rename the finished file into place");
}

std::string number(double value, const char* format = "%.6g", const char* missing = "")
{
    if (std::isnan(value))
        return missing;
    char text[64];
    std::snprintf(text, sizeof(text), format, value);
    return text;
}

std::string csvText(const std::string& text)
{
    std::string out = "\"";
    for (char c : text)
        out += c == '"' ? std::string("\"\"") : std::string(1, c);
    return out + "\"";
}

// Pass time (median) summed per stage group.
std::vector<double> stageTimes(const Record& r)
{
    std::vector<double> times(kStageGroupCount, 0.0);
    for (const PassSummary& pass : r.passes)
        times[stageGroupOf(pass.name)] += pass.medianMs;
    return times;
}

// Compaction + trace: the tracer's whole cost (before stop 48 lavapipe's timestamps could split
// them wrongly; vk::writeTimestamp).
double srtTraceMs(const Record& r)
{
    std::vector<double> times = stageTimes(r);
    return times[2] + times[3];
}

bool isGpuMethod(const Record& r)
{
    return r.method != "oracle";
}

// "1.2M", "250k", "900".
std::string shortCount(uint64_t n)
{
    char text[32];
    if (n >= 1'000'000)
        std::snprintf(text, sizeof(text), "%.3gM", double(n) / 1e6);
    else if (n >= 1'000)
        std::snprintf(text, sizeof(text), "%.3gk", double(n) / 1e3);
    else
        std::snprintf(text, sizeof(text), "%llu", (unsigned long long)n);
    return text;
}

// CSV with one schema for every section.
std::string recordsCsv(const std::vector<Record>& records, const std::string& section)
{
    std::ostringstream out;
    out << "section,scene,triangles,level,light_radius,method,shadow,available,note,width,height,frames,"
           "median_ms,best_ms,cpu_median_ms,pip_fraction,penumbra_fraction,rays,nodes_visited,nodes_per_ray,error,"
           "bytes_per_triangle,simplify_error,device_bytes,peak_rss_bytes,device,driver,light_samples\n";
    for (const Record& r : records) {
        if (r.section != section)
            continue;
        out << r.section << ',' << r.scene << ',' << r.triangles << ',' << number(r.level) << ','
            << number(r.lightRadius) << ',' << r.method << ',' << shadowKindName(r.kind) << ',' << (r.available ? 1 : 0)
            << ',' << csvText(r.note) << ',' << r.width << ',' << r.height << ',' << r.frames << ','
            << number(r.medianMs) << ',' << number(r.bestMs) << ',' << number(r.cpuMedianMs) << ','
            << number(r.pipFraction) << ',' << number(r.penumbraFraction) << ',' << r.rays << ',' << r.nodesVisited
            << ',' << number(r.rays ? double(r.nodesVisited) / double(r.rays) : kNoValue) << ',' << number(r.error)
            << ',' << number(r.bytesPerTriangle) << ',' << number(r.simplifyError) << ',' << r.deviceBytes << ','
            << r.peakRssBytes << ',' << csvText(r.device) << ',' << csvText(r.driver) << ',' << r.lightSamples << '\n';
    }
    return out.str();
}

std::string stagesCsv(const std::vector<Record>& records)
{
    std::ostringstream out;
    out << "scene,triangles,method,shadow";
    for (const char* group : kStageGroups)
        out << ',' << group << "_ms";
    out << ",total_ms,passes,device,driver\n";
    for (const Record& r : records) {
        if (r.section != "methods" || !r.available || !isGpuMethod(r))
            continue;
        std::vector<double> times = stageTimes(r);
        double total = 0;
        out << r.scene << ',' << r.triangles << ',' << r.method << ',' << shadowKindName(r.kind);
        for (double t : times) {
            out << ',' << number(t);
            total += t;
        }
        std::string passes;
        for (const PassSummary& pass : r.passes)
            passes += (passes.empty() ? "" : " ") + pass.name + "=" + number(pass.medianMs, "%.3f");
        out << ',' << number(total) << ',' << csvText(passes) << ',' << csvText(r.device) << ',' << csvText(r.driver)
            << '\n';
    }
    return out.str();
}

nlohmann::json jsonNumber(double value)
{
    return std::isnan(value) ? nlohmann::json(nullptr) : nlohmann::json(value);
}

std::string recordsJson(const SuiteResults& results)
{
    nlohmann::json root;
    root["suite"] = results.options.suite;
    root["date"] = results.date;
    root["device"] = results.device.name;
    root["driver"] = results.device.driver;
    root["vulkan"] = results.device.apiVersion;
    root["size"] = results.options.size;
    root["frames"] = results.options.frames;
    root["light_samples"] = results.options.lightSamples;
    root["afsm_samples"] = results.options.afsmSamples;
    root["afsm_sample_counts"] = results.options.afsmSampleCounts;
    root["penumbra_maps"] = results.options.penumbraMaps;
    root["soft_shadow_maps"] = results.options.softShadowMaps;
    root["soft_light_radius"] = results.options.softLightRadius;
    root["scenes"] = nlohmann::json::array();
    for (const BenchScene& scene : results.options.scenes)
        root["scenes"].push_back({{"name", scene.name}, {"triangles", scene.triangles}});
    root["scan_triangles"] = results.options.scanTriangles;
    root["levels"] = results.options.levels;
    root["sweep_scene"] = results.options.sweepScene;
    root["light_radii"] = results.options.lightRadii;
    root["records"] = nlohmann::json::array();
    for (const Record& r : results.records) {
        nlohmann::json j;
        j["section"] = r.section;
        j["scene"] = r.scene;
        j["triangles"] = r.triangles;
        j["level"] = r.level;
        j["light_radius"] = r.lightRadius;
        j["light_samples"] = r.lightSamples;
        j["method"] = r.method;
        j["shadow"] = shadowKindName(r.kind);
        j["available"] = r.available;
        j["note"] = r.note;
        j["width"] = r.width;
        j["height"] = r.height;
        j["frames"] = r.frames;
        j["median_ms"] = jsonNumber(r.medianMs);
        j["best_ms"] = jsonNumber(r.bestMs);
        j["cpu_median_ms"] = jsonNumber(r.cpuMedianMs);
        j["passes"] = nlohmann::json::array();
        for (const PassSummary& pass : r.passes)
            j["passes"].push_back({{"name", pass.name}, {"median_ms", pass.medianMs}, {"best_ms", pass.bestMs}});
        if (r.available && isGpuMethod(r)) {
            std::vector<double> times = stageTimes(r);
            for (size_t g = 0; g < kStageGroupCount; ++g)
                j["stages_ms"][kStageGroups[g]] = times[g];
        }
        j["pip_fraction"] = jsonNumber(r.pipFraction);
        j["penumbra_fraction"] = jsonNumber(r.penumbraFraction);
        j["rays"] = r.rays;
        j["nodes_visited"] = r.nodesVisited;
        if (r.rhPeakPairBytes)
            j["rh_peak_pair_bytes"] = r.rhPeakPairBytes;
        j["error"] = jsonNumber(r.error);
        j["bytes_per_triangle"] = jsonNumber(r.bytesPerTriangle);
        j["simplify_error"] = jsonNumber(r.simplifyError);
        j["device_bytes"] = r.deviceBytes;
        j["peak_rss_bytes"] = r.peakRssBytes;
        j["device"] = r.device;
        j["driver"] = r.driver;
        root["records"].push_back(std::move(j));
    }
    return root.dump(1) + "\n";
}

const Record* findRecord(const std::vector<Record>& records, const std::string& section, const std::string& scene,
                         const std::string& method, ShadowKind kind, double level = 1.0, double radius = -1.0)
{
    for (const Record& r : records)
        if (r.section == section && r.scene == scene && r.method == method && r.kind == kind && r.level == level &&
            (radius < 0.0 || r.lightRadius == radius))
            return &r;
    return nullptr;
}

std::vector<std::string> scenesOf(const std::vector<Record>& records, const std::string& section)
{
    std::vector<std::string> scenes;
    for (const Record& r : records)
        if (r.section == section && std::find(scenes.begin(), scenes.end(), r.scene) == scenes.end())
            scenes.push_back(r.scene);
    return scenes;
}

// Least-squares slope of log(ms) against log(triangles): 1 is linear growth,
// near 0 is logarithmic or flat.
double logLogSlope(const std::vector<std::pair<double, double>>& points)
{
    if (points.size() < 2)
        return kNoValue;
    double sx = 0, sy = 0, sxx = 0, sxy = 0, n = double(points.size());
    for (auto [x, y] : points) {
        double lx = std::log(x), ly = std::log(y);
        sx += lx;
        sy += ly;
        sxx += lx * lx;
        sxy += lx * ly;
    }
    double d = n * sxx - sx * sx;
    return d != 0 ? (n * sxy - sx * sy) / d : kNoValue;
}

std::vector<double> levelsOf(const std::vector<Record>& records)
{
    std::set<double> levels;
    for (const Record& r : records)
        if (r.section == "scalability")
            levels.insert(r.level);
    return {levels.begin(), levels.end()};
}

bool hasSection(const std::vector<Record>& records, const std::string& section)
{
    return std::any_of(records.begin(), records.end(), [&](const Record& r) { return r.section == section && r.available; });
}

std::vector<double> radiiOf(const std::vector<Record>& records)
{
    std::set<double> radii;
    for (const Record& r : records)
        if (r.section == "light_size" && r.kind == ShadowKind::Soft && r.available)
            radii.insert(r.lightRadius);
    return {radii.begin(), radii.end()};
}

// One row of the floor table: a stage, its floor, time / floor.
struct FloorRow {
    std::string scene, shadow, method, stage;
    double ms, floorMs;
    double ratio() const { return floorMs > 0 ? ms / floorMs : kNoValue; }
};

// Every stage of sm and srt against its floor (RenderSettings::measureFloors),
// then the tracer against Embree on the same rays: frt's compaction + trace
// against the oracle's time for the same number of rays (both trace every
// light-facing pixel of the same G-buffer).
std::vector<FloorRow> floorRows(const std::vector<Record>& records)
{
    std::vector<FloorRow> rows;
    for (const Record& r : records)
        if (r.section == "methods")
            for (const FloorSummary& f : r.floors)
                rows.push_back({r.scene, shadowKindName(r.kind), r.method, f.stage, f.ms, f.floorMs});
    for (const Record& r : records) {
        if (r.section != "methods" || r.method != "frt" || !r.available || !r.rays)
            continue;
        const Record* oracle = findRecord(records, "methods", r.scene, "oracle", r.kind);
        if (!oracle || !oracle->rays)
            continue;
        double traceMs = 0;
        for (const PassSummary& pass : r.passes)
            if (pass.name == "trace" || pass.name == "compact")
                traceMs += pass.medianMs;
        const double embreeMs = oracle->medianMs * double(r.rays) / double(oracle->rays);
        rows.push_back({r.scene, shadowKindName(r.kind), "frt", "trace (Embree)", traceMs, embreeMs});
    }
    return rows;
}

std::string floorsCsv(const std::vector<Record>& records)
{
    std::ostringstream out;
    out << "scene,shadow,method,stage,ms,floor_ms,time_over_floor\n";
    for (const FloorRow& f : floorRows(records))
        out << f.scene << ',' << f.shadow << ',' << f.method << ',' << csvText(f.stage) << ',' << number(f.ms) << ','
            << number(f.floorMs) << ',' << number(f.ratio()) << '\n';
    return out.str();
}

struct Plot {
    std::string script; // gnuplot script in the results folder
    std::string png;    // one image it writes
};

// Plot data (whitespace separated, "?" missing) and gnuplot scripts. Returns
// the PNGs the scripts make.
std::vector<Plot> writePlotScripts(const SuiteResults& results, const fs::path& dir)
{
    const std::vector<Record>& records = results.records;
    std::vector<Plot> pngs;
    std::string title = results.device.name + ", " + results.device.driver;
    std::string header =
        "set terminal pngcairo size 1100,650 noenhanced font ',10'\nset datafile missing '?'\nset key outside right\n"
        "set grid ytics\n";

    // Figure 8: median frame time per method and scene.
    {
        std::ostringstream data;
        data << "# scene sm srt frt oracle afsm (median ms, hard shadows)\n";
        for (const std::string& scene : scenesOf(records, "methods")) {
            const Record* sm = findRecord(records, "methods", scene, "sm", ShadowKind::Hard);
            data << '"' << scene << ' ' << (sm ? shortCount(sm->triangles) : "") << '"';
            for (const char* method : kMethodOrder) {
                const Record* r = findRecord(records, "methods", scene, method, ShadowKind::Hard);
                data << ' ' << (r ? number(r->medianMs, "%.3f", "?") : "?");
            }
            data << '\n';
        }
        writeFile(dir / "methods.dat", data.str());
        writeFile(dir / "methods.gp",
                  header + "set output 'methods.png'\nset title 'Hard shadows per method (median ms per frame), " +
                      title +
                      "'\nset style data histogram\nset style histogram cluster gap 1\n"
                      "set style fill solid 0.8 border -1\nset logscale y\nset ylabel 'ms'\n"
                      "plot 'methods.dat' using 2:xtic(1) title 'sm', '' using 3 title 'srt', "
                      "'' using 4 title 'frt', '' using 5 title 'Embree oracle (CPU)', '' using 6 title 'afsm'\n");
        pngs.push_back({"methods.gp", "methods.png"});
    }

    // Figure 9: time per stage.
    {
        std::ostringstream data;
        data << "# label";
        for (const char* group : kStageGroups)
            data << ' ' << group;
        data << '\n';
        for (const Record& r : records) {
            if (r.section != "methods" || !r.available || !isGpuMethod(r))
                continue;
            data << '"' << r.scene << ' ' << r.method << (r.kind == ShadowKind::Soft ? " soft" : "") << '"';
            for (double t : stageTimes(r))
                data << ' ' << number(t, "%.3f");
            data << '\n';
        }
        writeFile(dir / "stages.dat", data.str());
        std::string plot = "plot 'stages.dat' using 2:xtic(1) title '" + std::string(kStageGroups[0]) + "'";
        for (size_t g = 1; g < kStageGroupCount; ++g)
            plot += ", '' using " + std::to_string(g + 2) + " title '" + kStageGroups[g] + "'";
        writeFile(dir / "stages.gp",
                  header + "set output 'stages.png'\nset title 'Time per stage (median GPU ms), " + title +
                      "'\nset style data histogram\nset style histogram rowstacked\n"
                      "set style fill solid 0.8 border -1\nset boxwidth 0.7\nset xtics rotate by -45\n"
                      "set ylabel 'ms'\n" +
                      plot + "\n");
        pngs.push_back({"stages.gp", "stages.png"});
    }

    // Every stage against its floor.
    if (!floorRows(records).empty()) {
        std::ostringstream data;
        data << "# label time/floor\n";
        for (const FloorRow& f : floorRows(records))
            data << '"' << f.scene << ' ' << f.method << (f.shadow == "soft" ? " soft " : " ") << f.stage << "\" "
                 << number(f.ratio(), "%.3f", "?") << '\n';
        writeFile(dir / "floors.dat", data.str());
        writeFile(dir / "floors.gp",
                  header + "set terminal pngcairo size 1800,700 noenhanced font ',9'\nset output 'floors.png'\nset title 'Each stage against its floor (time / floor, 1 = at the floor), " +
                      title +
                      "'\nset style data histogram\nset style fill solid 0.8 border -1\n"
                      "set xtics rotate by -70 font ',7'\nset logscale y\nset ylabel 'time / floor'\nset boxwidth 0.8\n"
                      "plot 'floors.dat' using 2:xtic(1) notitle\n");
        pngs.push_back({"floors.gp", "floors.png"});
    }

    // Figure 7 (left): time per simplification level, log-log; nodes per ray.
    std::vector<double> levels = levelsOf(records);
    if (!levels.empty()) {
        std::ostringstream data;
        data << "# triangles sm srt frt oracle afsm (median ms) srt_nodes_per_ray frt_nodes_per_ray srt_trace_ms "
                "(compaction + trace)\n";
        for (double level : levels) {
            const Record* any = findRecord(records, "scalability", "scan", "sm", ShadowKind::Hard, level);
            if (!any)
                continue;
            data << any->triangles;
            for (const char* method : kMethodOrder) {
                const Record* r = findRecord(records, "scalability", "scan", method, ShadowKind::Hard, level);
                data << ' ' << (r ? number(r->medianMs, "%.3f", "?") : "?");
            }
            for (const char* method : {"srt", "frt"}) {
                const Record* r = findRecord(records, "scalability", "scan", method, ShadowKind::Hard, level);
                data << ' ' << (r && r->rays ? number(double(r->nodesVisited) / double(r->rays), "%.3f") : "?");
            }
            const Record* srt = findRecord(records, "scalability", "scan", "srt", ShadowKind::Hard, level);
            data << ' ' << (srt ? number(srtTraceMs(*srt), "%.3f", "?") : "?");
            data << '\n';
        }
        writeFile(dir / "scalability.dat", data.str());
        std::string script = header;
        script += "set output 'scalability.png'\n";
        script += "set title 'scan: time per simplification level (log-log), " + title + "'\n";
        script += "set logscale xy\nset grid xtics ytics mxtics mytics\n";
        script += "set xlabel 'triangles'\nset ylabel 'ms per frame'\n";
        script += "plot 'scalability.dat' using 1:2 with linespoints title 'sm', "
                  "'' using 1:3 with linespoints title 'srt', "
                  "'' using 1:4 with linespoints title 'frt', "
                  "'' using 1:5 with linespoints title 'Embree oracle (CPU)', "
                  "'' using 1:6 with linespoints title 'afsm', "
                  "'' using 1:9 with linespoints dashtype 2 title 'srt compaction + trace'\n";
        script += "set output 'scalability_nodes.png'\n";
        script += "set title 'scan: BVH nodes visited per shadow ray, " + title + "'\n";
        script += "unset logscale y\nset ylabel 'nodes per ray'\n";
        script += "plot 'scalability.dat' using 1:7 with linespoints title 'srt', "
                  "'' using 1:8 with linespoints title 'frt'\n";
        writeFile(dir / "scalability.gp", script);
        pngs.push_back({"scalability.gp", "scalability.png"});
        pngs.push_back({"scalability.gp", "scalability_nodes.png"});
    }

    // Figure 7 (right): soft-shadow time and penumbra fraction against the light radius.
    std::vector<double> radii = radiiOf(records);
    if (!radii.empty()) {
        std::string scene = results.options.sweepScene;
        std::ostringstream data;
        data << "# radius sm srt frt oracle afsm (median ms) srt_penumbra_fraction oracle_penumbra_fraction\n";
        for (double radius : radii) {
            data << number(radius);
            for (const char* method : kSoftMethodOrder) {
                const Record* r = findRecord(records, "light_size", scene, method, ShadowKind::Soft, 1.0, radius);
                data << ' ' << (r ? number(r->medianMs, "%.3f", "?") : "?");
            }
            for (const char* method : {"srt", "oracle"}) {
                const Record* r = findRecord(records, "light_size", scene, method, ShadowKind::Soft, 1.0, radius);
                data << ' ' << (r ? number(r->penumbraFraction, "%.5f", "?") : "?");
            }
            data << '\n';
        }
        writeFile(dir / "light_size.dat", data.str());
        std::string script = header;
        script += "set output 'light_size.png'\n";
        script += "set title '" + scene + ": soft shadows against light radius, " + title + "'\n";
        script += "set logscale x\nset xlabel 'light radius (fraction of the scene diagonal)'\n";
        script += "set ylabel 'ms per frame'\nset y2label 'penumbra fraction'\nset y2tics\nset ytics nomirror\n";
        script += "set yrange [0:*]\nset y2range [0:*]\n";
        script += "plot 'light_size.dat' using 1:2 with linespoints title 'sm', "
                  "'' using 1:3 with linespoints title 'srt', "
                  "'' using 1:4 with linespoints title 'frt', "
                  "'' using 1:5 with linespoints title 'Embree oracle (CPU)', "
                  "'' using 1:6 with linespoints title 'afsm (" + std::to_string(results.options.afsmSamples) + " samples)', "
                  "'' using 1:7 axes x1y2 with lines dashtype 2 title 'srt penumbra fraction', "
                  "'' using 1:8 axes x1y2 with lines dashtype 3 title 'oracle penumbra fraction'\n";
        writeFile(dir / "light_size.gp", script);
        pngs.push_back({"light_size.gp", "light_size.png"});
    }

    // afsm, the paper's Figures 11-13: soft-shadow time against the triangle
    // count (scan levels; hard shadows beside), the light radius (the sweep
    // above) and the number of light samples.
    if (hasSection(records, "afsm_triangles")) {
        std::ostringstream data;
        data << "# triangles afsm_soft_ms afsm_hard_ms frt_hard_ms\n";
        for (double level : levels) {
            const Record* soft = findRecord(records, "afsm_triangles", "scan", "afsm", ShadowKind::Soft, level, -1.0);
            if (!soft)
                continue;
            const Record* hard = findRecord(records, "scalability", "scan", "afsm", ShadowKind::Hard, level);
            const Record* frt = findRecord(records, "scalability", "scan", "frt", ShadowKind::Hard, level);
            data << soft->triangles << ' ' << number(soft->medianMs, "%.3f", "?") << ' ' << (hard ? number(hard->medianMs, "%.3f", "?") : "?")
                 << ' ' << (frt ? number(frt->medianMs, "%.3f", "?") : "?") << '\n';
        }
        writeFile(dir / "afsm_triangles.dat", data.str());
        writeFile(dir / "afsm_triangles.gp",
                  header + "set output 'afsm_triangles.png'\nset title 'afsm: time against triangles (scan levels, log-log; the paper''s Figure 11), " +
                      title + "'\nset logscale xy\nset grid xtics ytics mxtics mytics\nset xlabel 'triangles'\nset ylabel 'ms per frame'\n"
                      "plot 'afsm_triangles.dat' using 1:2 with linespoints title 'afsm soft (" +
                      std::to_string(results.options.afsmSampleCounts.empty() ? 128u : results.options.afsmSampleCounts.front()) +
                      " samples)', '' using 1:3 with linespoints title 'afsm hard', '' using 1:4 with linespoints dashtype 2 title 'frt hard'\n");
        pngs.push_back({"afsm_triangles.gp", "afsm_triangles.png"});
    }
    if (hasSection(records, "afsm_samples")) {
        std::ostringstream data;
        data << "# samples afsm_soft_ms error\n";
        for (const Record& r : records)
            if (r.section == "afsm_samples" && r.available)
                data << r.lightSamples << ' ' << number(r.medianMs, "%.3f", "?") << ' ' << number(r.error, "%.6f", "?") << '\n';
        writeFile(dir / "afsm_samples.dat", data.str());
        writeFile(dir / "afsm_samples.gp",
                  header + "set output 'afsm_samples.png'\nset title 'afsm: soft-shadow time against light samples (the paper''s Figure 13), " +
                      results.options.sweepScene + ", " + title + "'\nset logscale x 2\nset xlabel 'light samples'\nset ylabel 'ms per frame'\n"
                      "set yrange [0:*]\nplot 'afsm_samples.dat' using 1:2 with linespoints title 'afsm soft'\n");
        pngs.push_back({"afsm_samples.gp", "afsm_samples.png"});
    }
    return pngs;
}

std::string shellQuote(const std::string& text)
{
    std::string out = "'";
    for (char c : text)
        out += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return out + "'";
}

// Runs gnuplot on every script; returns the plots made, empty when gnuplot is missing.
std::vector<std::string> runGnuplot(const fs::path& dir, const std::vector<Plot>& plots, bool& gnuplotFound)
{
    gnuplotFound = std::system("command -v gnuplot > /dev/null 2>&1") == 0;
    if (!gnuplotFound)
        return {};
    std::vector<std::string> made;
    std::set<std::string> scripts;
    for (const Plot& plot : plots)
        fs::remove(dir / plot.png);
    for (const Plot& plot : plots)
        scripts.insert(plot.script);
    for (const std::string& script : scripts) {
        std::string command = "cd " + shellQuote(dir.string()) + " && gnuplot " + shellQuote(script) + " 2> " +
                              shellQuote(script + ".log");
        if (std::system(command.c_str()) == 0)
            fs::remove(dir / (script + ".log"));
    }
    for (const Plot& plot : plots)
        if (fs::exists(dir / plot.png))
            made.push_back(plot.png);
    return made;
}

std::string ms(double value)
{
    return number(value, "%.1f", "–");
}

std::string percent(double fraction)
{
    return std::isnan(fraction) ? "–" : number(fraction * 100.0, "%.3f") + "%";
}

std::string summaryMarkdown(const SuiteResults& results, const std::vector<std::string>& plots,
                            const std::string& plotNote)
{
    const std::vector<Record>& records = results.records;
    const SuiteOptions& o = results.options;
    std::ostringstream md;
    md << "# Penumbra benchmark: " << o.suite << "\n\n";
    md << "- date: " << results.date << "\n";
    md << "- device: " << results.device.name << " (" << results.device.type << "), driver " << results.device.driver
       << ", Vulkan " << results.device.apiVersion << "\n";
    md << "- image " << o.size << "x" << o.size << ", " << o.frames
       << " timed frame(s) per case after one warm-up frame (on a GPU, warm-up frames for half a second) and the untimed frames "
          "until the occlusion culling is steady (the most a view drew in 5 frames in a row stopped falling); a scene's methods take "
          "turns frame by frame; GPU times from timestamp queries, the Embree oracle's on "
          "the CPU\n";
    md << "- command: `penumbra bench " << o.suite << " --out " << o.outDir << " --size " << o.size << " --frames "
       << o.frames << " --scan-triangles " << o.scanTriangles << " --light-samples " << o.lightSamples
       << " --penumbra-maps " << o.penumbraMaps << " --soft-shadow-maps " << o.softShadowMaps << " --afsm-samples " << o.afsmSamples;
    auto list = [&](const char* option, const std::vector<std::string>& names) {
        for (size_t i = 0; i < names.size(); ++i)
            md << (i ? "," : std::string(" ") + option + " ") << names[i];
    };
    list("--methods", o.methods);
    list("--sections", o.sections);
    md << "`\n";
    for (const std::string& note : results.notes)
        md << "- " << note << "\n";
    md << "- " << plotNote << "\n\n";

    md << "## Methods (Figure 8)\n\n"
          "Median (best) ms per frame. Error: share of light-facing pixels whose visibility differs from the Embree "
          "oracle on the same G-buffer (soft: mean absolute difference). PIP: pixels given rays / covered pixels.\n\n";
    md << "| scene | triangles | B/tri | shadow | method | median ms | best ms | PIP | penumbra | rays | nodes/ray "
          "| error | device MB | peak RSS MB |\n"
          "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const Record& r : records) {
        if (r.section != "methods")
            continue;
        md << "| " << r.scene << " | " << shortCount(r.triangles) << " | " << number(r.bytesPerTriangle, "%.2f", "–")
           << " | " << shadowKindName(r.kind) << " | " << r.method << " | ";
        if (!r.available) {
            md << r.note << " | | | | | | | | | |\n";
            continue;
        }
        md << ms(r.medianMs) << " | " << ms(r.bestMs) << " | " << percent(isGpuMethod(r) ? r.pipFraction : kNoValue)
           << " | " << percent(r.penumbraFraction) << " | " << r.rays << " | "
           << number(r.nodesVisited ? double(r.nodesVisited) / double(r.rays) : kNoValue, "%.1f", "–") << " | "
           << (isGpuMethod(r) ? percent(r.error) : "reference") << " | "
           << (isGpuMethod(r) ? number(double(r.deviceBytes) / 1048576.0, "%.1f") : "–") << " | "
           << number(double(r.peakRssBytes) / 1048576.0, "%.0f") << " |\n";
    }

    md << "\n### Frame times and rates (hard shadows, median ms, frames per second)\n\n"
          "| scene | sm | srt | frt | oracle | afsm | rh | frt / srt | srt / sm | afsm / sm | afsm / srt | rh / frt |\n"
          "|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const std::string& scene : scenesOf(records, "methods")) {
        md << "| " << scene;
        const char* names[] = {"sm", "srt", "frt", "oracle", "afsm", "rh"}; // rh: where the scene's light is one it takes
        double values[6];
        for (int m = 0; m < 6; ++m) {
            const Record* r = findRecord(records, "methods", scene, names[m], ShadowKind::Hard);
            values[m] = r && r->available ? r->medianMs : kNoValue;
            md << " | " << ms(values[m]);
            if (m != 3)
                md << " (" << number(1000.0 / values[m], "%.2f", "–") << " fps)";
        }
        md << " | " << number(values[2] / values[1], "%.2fx", "–") << " | " << number(values[1] / values[0], "%.2fx", "–") << " | "
           << number(values[4] / values[0], "%.2fx", "–") << " | " << number(values[4] / values[1], "%.2fx", "–") << " | "
           << number(values[5] / values[2], "%.2fx", "–") << " |\n";
    }

    if (!scenesOf(records, "point").empty()) {
        md << "\n## Omni-directional light: a point light among the geometry (rh)\n\n"
              "Hard shadows of a point light a quarter of the height above each scene's centre: sm and srt draw a cube map, "
              "frt traces every light-facing pixel, rh (Olsson and Assarsson 2011) bounds all the light's rays with one cone hierarchy, "
              "no map. afsm is left out here (its casters near the light cover whole cube faces: minutes per frame on "
              "lavapipe). Median ms per frame; error as in the methods table.\n\n"
              "| scene | sm | srt | frt | rh | oracle | rh / frt | rh / srt | rh error | frt error |\n|---|---|---|---|---|---|---|---|---|---|\n";
        for (const std::string& scene : scenesOf(records, "point")) {
            const char* names[] = {"sm", "srt", "frt", "rh", "oracle"};
            double values[5];
            md << "| " << scene;
            for (int m = 0; m < 5; ++m) {
                const Record* r = findRecord(records, "point", scene, names[m], ShadowKind::Hard);
                values[m] = r ? r->medianMs : kNoValue;
                md << " | " << ms(values[m]);
            }
            const Record* rh = findRecord(records, "point", scene, "rh", ShadowKind::Hard);
            const Record* frt = findRecord(records, "point", scene, "frt", ShadowKind::Hard);
            md << " | " << number(values[3] / values[2], "%.2fx", "–") << " | " << number(values[3] / values[1], "%.2fx", "–") << " | "
               << percent(rh ? rh->error : kNoValue) << " | " << percent(frt ? frt->error : kNoValue) << " |\n";
        }
    }
    if (!scenesOf(records, "rh_variants").empty()) {
        md << "\n### Cone ray hierarchy variants (the paper's Table 2)\n\n"
              "rh under the point light with each cone/triangle test (precise: section 3.2; spheres: bounding spheres) and the rays "
              "sorted by direction (section 3.5) or not (screen-space 2x2 blocks), early accept on (section 3.3) and one pass; "
              "then the precise test on sorted rays with early accept off, and with the two-pass traversal (section 3.4). Cone "
              "tests are the paper's nodes visited; peak pairs is the most traversal memory in use at once (the arena is 32 MiB, "
              "bounded).\n\n"
              "| scene | variant | median ms | cone tests | cone tests / ray | peak pairs MiB | note |\n|---|---|---|---|---|---|---|\n";
        for (const Record& r : records) {
            if (r.section != "rh_variants")
                continue;
            md << "| " << r.scene << " | " << r.method << " | " << ms(r.medianMs) << " | " << shortCount(r.nodesVisited) << " | "
               << number(r.rays ? double(r.nodesVisited) / double(r.rays) : kNoValue, "%.1f", "–") << " | "
               << number(double(r.rhPeakPairBytes) / 1048576.0, "%.1f") << " | " << r.note << " |\n";
        }
    }

    md << "\n## Time per stage (Figure 9)\n\n"
          "Median GPU ms per stage: raster = camera + shadow_map, PIP = thin_triangles + penumbra_mask (soft) + "
          "classify, compaction = compact, trace, shading = shade, transfers = readback to the CPU. "
          "Total is the sum of the stage medians, so it can differ from the median frame time above.\n\n";
    md << "| scene | shadow | method";
    for (const char* group : kStageGroups)
        md << " | " << group;
    md << " | total |\n|---|---|---";
    for (size_t g = 0; g <= kStageGroupCount; ++g)
        md << "|---";
    md << "|\n";
    for (const Record& r : records) {
        if (r.section != "methods" || !r.available || !isGpuMethod(r))
            continue;
        std::vector<double> times = stageTimes(r);
        double total = 0;
        md << "| " << r.scene << " | " << shadowKindName(r.kind) << " | " << r.method;
        for (double t : times) {
            md << " | " << ms(t);
            total += t;
        }
        md << " | " << ms(total) << " |\n";
    }

    const std::vector<FloorRow> floors = floorRows(records);
    if (!floors.empty()) {
        md << "\n## Every stage against its floor\n\n"
              "Medians over floor frames (RenderSettings::measureFloors, `penumbra render --floors`). The floor of a "
              "per-pixel pass (view_fit, classify, compact, shade) is its null twin (shaders/floor.glsli): the same "
              "bindings and dispatch, every input read once per pixel, the outputs written. The floor of a raster "
              "pass (camera, shadow_map) is every triangle of the model drawn uncompressed, depth only, unculled. "
              "The tracer's floor is Embree on the same rays on the "
              "CPU: frt's compaction + trace against the oracle's time for as many rays. Goal: every stage within 2x, "
              "the tracer within 4x.\n\n"
              "| scene | shadow | method | stage | ms | floor ms | time / floor |\n|---|---|---|---|---|---|---|\n";
        for (const FloorRow& f : floors)
            md << "| " << f.scene << " | " << f.shadow << " | " << f.method << " | " << f.stage << " | " << ms(f.ms) << " | "
               << ms(f.floorMs) << " | " << number(f.ratio(), "%.1fx", "-") << " |\n";
    }

    std::vector<double> levels = levelsOf(records);
    if (!levels.empty()) {
        md << "\n## Scalability over simplification levels (Figure 7, left)\n\n"
              "One `scan` model, each level simplified from the next larger one with meshoptimizer, hard shadows, "
              "median ms per frame.\n\n";
        md << "| level | triangles | B/tri | sm | srt | frt | oracle | afsm | srt compaction + trace | srt PIP "
              "| srt nodes/ray | frt nodes/ray | srt error |\n"
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
        std::map<std::string, std::vector<std::pair<double, double>>> series;
        for (double level : levels) {
            const Record* sm = findRecord(records, "scalability", "scan", "sm", ShadowKind::Hard, level);
            if (!sm)
                continue;
            md << "| 1/" << number(1.0 / level, "%.0f") << " | " << shortCount(sm->triangles) << " | "
               << number(sm->bytesPerTriangle, "%.2f") << " | ";
            for (const char* method : kMethodOrder) {
                const Record* r = findRecord(records, "scalability", "scan", method, ShadowKind::Hard, level);
                md << (r ? ms(r->medianMs) : "–") << " | ";
                if (r && r->available && r->medianMs > 0)
                    series[method].push_back({double(r->triangles), r->medianMs});
            }
            const Record* srt = findRecord(records, "scalability", "scan", "srt", ShadowKind::Hard, level);
            const Record* frt = findRecord(records, "scalability", "scan", "frt", ShadowKind::Hard, level);
            if (srt && srt->available && srtTraceMs(*srt) > 0)
                series["srt compaction + trace"].push_back({double(srt->triangles), srtTraceMs(*srt)});
            if (srt && srt->nodesVisited)
                series["srt nodes/ray"].push_back(
                    {double(srt->triangles), double(srt->nodesVisited) / double(srt->rays)});
            md << (srt ? ms(srtTraceMs(*srt)) : "–") << " | " << percent(srt ? srt->pipFraction : kNoValue) << " | "
               << number(srt && srt->rays ? double(srt->nodesVisited) / double(srt->rays) : kNoValue, "%.1f", "–")
               << " | "
               << number(frt && frt->rays ? double(frt->nodesVisited) / double(frt->rays) : kNoValue, "%.1f", "–")
               << " | " << percent(srt ? srt->error : kNoValue) << " |\n";
        }
        md << "\nGrowth: least-squares slope of log(value) against log(triangles) (1 = linear in the triangle "
              "count, 0 = flat; logarithmic growth shows as a small slope that shrinks with size):";
        for (const char* method : {"sm", "srt", "frt", "oracle", "afsm", "srt compaction + trace", "srt nodes/ray"})
            md << " " << method << " " << number(logLogSlope(series[method]), "%.2f", "–") << ";";
        md << " ratio largest / smallest level:";
        for (const char* method : {"sm", "srt", "frt", "oracle", "afsm", "srt compaction + trace", "srt nodes/ray"}) {
            const auto& s = series[method];
            md << " " << method << " " << (s.size() >= 2 ? number(s.back().second / s.front().second, "%.2fx") : "–")
               << ";";
        }
        md << " for "
           << (series["sm"].size() >= 2 ? number(series["sm"].back().first / series["sm"].front().first, "%.0fx") : "–")
           << " the triangles.\n";
    }

    md << "\n## Light-size sweep, soft shadows (Figure 7, right)\n\n";
    std::vector<double> radii = radiiOf(records);
    if (radii.empty()) {
        md << "Scene `" << o.sweepScene << "`, sphere-light radius as a fraction of the scene diagonal: ";
        for (double radius : o.lightRadii)
            md << number(radius) << " ";
        md << "— no soft-shadow records in this run.\n";
    } else {
        md << "Scene `" << o.sweepScene << "`, " << o.lightSamples << " light samples, " << o.penumbraMaps
           << " penumbra map(s); median ms per frame and penumbra fraction (covered pixels with 0 < visibility "
              "< 1).\n\n";
        md << "| radius | sm | srt | frt | oracle | afsm | srt penumbra | oracle penumbra | srt error | afsm error |\n"
              "|---|---|---|---|---|---|---|---|---|---|\n";
        for (double radius : radii) {
            md << "| " << number(radius);
            for (const char* method : kSoftMethodOrder) {
                const Record* r =
                    findRecord(records, "light_size", o.sweepScene, method, ShadowKind::Soft, 1.0, radius);
                md << " | " << (r ? ms(r->medianMs) : "–");
            }
            const Record* srt = findRecord(records, "light_size", o.sweepScene, "srt", ShadowKind::Soft, 1.0, radius);
            const Record* oracle =
                findRecord(records, "light_size", o.sweepScene, "oracle", ShadowKind::Soft, 1.0, radius);
            const Record* afsm = findRecord(records, "light_size", o.sweepScene, "afsm", ShadowKind::Soft, 1.0, radius);
            md << " | " << percent(srt ? srt->penumbraFraction : kNoValue) << " | "
               << percent(oracle ? oracle->penumbraFraction : kNoValue) << " | " << percent(srt ? srt->error : kNoValue) << " | "
               << percent(afsm ? afsm->error : kNoValue) << " |\n";
        }
        md << "\nafsm keeps " << o.afsmSamples
           << " light samples per view sample (its own, the table's); its error is against the oracle tracing those samples, "
              "so it is the table's discretization alone (the paper's Figure 12 is its time column).\n";
    }

    if (hasSection(records, "afsm_triangles") || hasSection(records, "afsm_samples")) {
        md << "\n## Alias-free shadow maps, soft shadows (the paper's Figures 11-13)\n\n"
              "afsm soft shadows from the sphere light of the methods' soft cases. Time against the triangle count (the scan "
              "levels of the scalability run, the paper's Figure 11, with its fewest samples), against the light radius (the "
              "light-size sweep above, Figure 12) and against the number of light samples (Figure 13, the paper: 128 -> 1024 "
              "samples roughly doubles the cost). Error: mean |visibility - oracle| against the oracle tracing the table's own "
              "samples (the table's discretization alone).\n\n"
              "| section | scene | triangles | samples | median ms | best ms | penumbra | error |\n|---|---|---|---|---|---|---|---|\n";
        for (const Record& r : records) {
            if (r.section != "afsm_triangles" && r.section != "afsm_samples")
                continue;
            md << "| " << r.section << " | " << r.scene << " | " << shortCount(r.triangles) << " | " << r.lightSamples << " | "
               << ms(r.medianMs) << " | " << ms(r.bestMs) << " | " << percent(r.penumbraFraction) << " | " << percent(r.error) << " |\n";
        }
        std::vector<std::pair<double, double>> bySamples;
        for (const Record& r : records)
            if (r.section == "afsm_samples" && r.available)
                bySamples.push_back({double(r.lightSamples), r.medianMs});
        if (bySamples.size() >= 2)
            md << "\nTime at " << number(bySamples.back().first, "%.0f") << " samples / time at " << number(bySamples.front().first, "%.0f")
               << ": " << number(bySamples.back().second / bySamples.front().second, "%.2fx") << ".\n";
    }

    if (!plots.empty()) {
        md << "\n## Plots\n\n";
        for (const std::string& plot : plots)
            md << "![" << plot << "](" << plot << ")\n\n";
    }
    md << "\n## Images\n\n"
          "Per scene: `-shadows.png` is sm | srt | frt | afsm | rh (point lights only) | oracle (N·L times visibility of the "
          "light), `-diff.png` is each method against the oracle in the same order (red: lit but the oracle shadows it; "
          "blue: the reverse), `-color.png` the rendered frames.\n\n";
    for (const std::string& image : results.images)
        md << "- [" << image << "](" << image << ")\n";
    md << "\n## Files\n\nmethods.csv / methods.json (every record of every section, with per-pass times in the JSON), "
          "stages.csv, floors.csv, scalability.csv, light_size.csv, point.csv, rh_variants.csv, afsm_triangles.csv, "
          "afsm_samples.csv; *.dat and *.gp are the plot data and gnuplot scripts "
          "(`gnuplot methods.gp` in this folder remakes a plot).\n";
    return md.str();
}

} // namespace

void writeSideBySide(const std::vector<Image>& panels, const std::string& path)
{
    if (panels.empty())
        return;
    constexpr uint32_t kGap = 4;
    uint32_t w = panels[0].width, h = panels[0].height;
    Image out;
    out.width = uint32_t(panels.size()) * w + uint32_t(panels.size() - 1) * kGap;
    out.height = h;
    out.rgba.assign(size_t(out.width) * out.height * 4, 1.0f);
    for (size_t p = 0; p < panels.size(); ++p) {
        if (panels[p].width != w || panels[p].height != h)
            fail(path, "side-by-side panels differ in size");
        for (uint32_t y = 0; y < h; ++y)
            std::copy_n(&panels[p].rgba[size_t(y) * w * 4], size_t(w) * 4,
                        &out.rgba[(size_t(y) * out.width + p * (w + kGap)) * 4]);
    }
    writeImage(out, path);
}

std::string writeReport(SuiteResults& results)
{
    fs::path dir = results.options.outDir;
    const std::vector<Record>& records = results.records;
    writeFile(dir / "methods.csv", recordsCsv(records, "methods"));
    writeFile(dir / "scalability.csv", recordsCsv(records, "scalability"));
    writeFile(dir / "light_size.csv", recordsCsv(records, "light_size"));
    writeFile(dir / "point.csv", recordsCsv(records, "point"));
    writeFile(dir / "rh_variants.csv", recordsCsv(records, "rh_variants"));
    writeFile(dir / "afsm_triangles.csv", recordsCsv(records, "afsm_triangles"));
    writeFile(dir / "afsm_samples.csv", recordsCsv(records, "afsm_samples"));
    writeFile(dir / "stages.csv", stagesCsv(records));
    writeFile(dir / "floors.csv", floorsCsv(records));
    writeFile(dir / "methods.json", recordsJson(results));

    std::vector<Plot> scripted = writePlotScripts(results, dir);
    std::vector<std::string> plots;
    std::string plotNote;
    if (!results.options.plots) {
        plotNote = "plots skipped (--no-plots): data and gnuplot scripts written";
    } else {
        bool gnuplotFound = false;
        plots = runGnuplot(dir, scripted, gnuplotFound);
        if (!gnuplotFound)
            plotNote = "plots skipped: gnuplot is not installed (data and *.gp scripts written)";
        else
            plotNote = "plots: " + std::to_string(plots.size()) + " of " + std::to_string(scripted.size()) +
                       " made with gnuplot";
    }
    if (radiiOf(records).empty())
        plotNote += "; no light-size plot (no soft-shadow data)";
    writeFile(dir / "summary.md", summaryMarkdown(results, plots, plotNote));
    return "penumbra bench: " + plotNote + "; results in " + dir.string();
}

} // namespace penumbra::bench
