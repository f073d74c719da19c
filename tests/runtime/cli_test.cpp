// The penumbra CLI end to end: real files in, images out, and one clear
// error line with a non-zero exit for every kind of bad input.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "cli_run.h"

namespace {

namespace fs = std::filesystem;

struct Result {
    int status = -1;
    std::string output; // stdout and stderr
};

// environment: "NAME=value ..." for this run only.
Result run(const std::string& arguments, const std::string& environment = "")
{
    Result result;
    result.status = penumbra::test::runCli(arguments, &result.output, environment);
    return result;
}

std::string tmp(const std::string& name)
{
    return std::string(PENUMBRA_TEST_TMP) + "/cli_" + name;
}

// One error line "penumbra: error: <subject>: <problem>" containing every fragment, exit status 1.
void expectError(const Result& result, std::initializer_list<std::string> fragments)
{
    EXPECT_EQ(result.status, 1) << result.output;
    EXPECT_EQ(result.output.rfind("penumbra: error: ", 0), 0u) << result.output;
    EXPECT_EQ(std::count(result.output.begin(), result.output.end(), '\n'), 1) << "expected one line:\n" << result.output;
    for (const std::string& fragment : fragments)
        EXPECT_NE(result.output.find(fragment), std::string::npos) << "missing '" << fragment << "' in: " << result.output;
}

TEST(Cli, HelpForEverySubcommand)
{
    for (const char* command : {"--help", "render --help", "generate --help", "preprocess --help", "info --help", "devices --help",
                                "bench --help"}) {
        Result result = run(command);
        EXPECT_EQ(result.status, 0) << command;
        EXPECT_NE(result.output.find("Usage"), std::string::npos) << command;
    }
}

TEST(Cli, GenerateThenRenderWithValidation)
{
    std::string model = tmp("city.glb"), image = tmp("city.png"), stats = tmp("city.json");
    fs::remove(image);
    Result generated = run("generate city --triangles 20000 --seed 3 -o " + model);
    ASSERT_EQ(generated.status, 0) << generated.output;
    Result rendered = run("render " + model + " -o " + image + " --size 256x192 --validation --stats " + stats);
    ASSERT_EQ(rendered.status, 0) << rendered.output;
    EXPECT_NE(rendered.output.find("triangles"), std::string::npos);
    EXPECT_NE(rendered.output.find("shadow_map"), std::string::npos);
    EXPECT_EQ(rendered.output.find("validation"), std::string::npos) << rendered.output;
    EXPECT_TRUE(fs::exists(image));
    EXPECT_GT(fs::file_size(image), 1000u);
    std::ifstream json(stats);
    std::string text((std::istreambuf_iterator<char>(json)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find("\"driver\""), std::string::npos) << text;
}

// --geometry-budget: the stats line and JSON report the pages (images: geometry_budget_test.cpp); bad budgets fail with one line.
TEST(Cli, RenderUnderAGeometryBudget)
{
    const std::string model = tmp("budget_city.glb"), unlimited = tmp("budget_unlimited.png"), budgeted = tmp("budget_budgeted.png"),
                      stats = tmp("budget.json");
    ASSERT_EQ(run("generate city --triangles 20000 --seed 3 -o " + model).status, 0);
    Result plain = run("render " + model + " -o " + unlimited + " --size 128x128 --shadows srt --validation");
    ASSERT_EQ(plain.status, 0) << plain.output;
    Result paged = run("render " + model + " -o " + budgeted + " --size 128x128 --shadows srt --validation --geometry-budget 0.1 "
                       "--geometry-page 6 --stats " + stats);
    ASSERT_EQ(paged.status, 0) << paged.output;
    EXPECT_NE(paged.output.find("| budget "), std::string::npos) << paged.output;
    EXPECT_NE(paged.output.find("pages uploaded"), std::string::npos) << paged.output;
    std::ifstream json(stats);
    std::string text((std::istreambuf_iterator<char>(json)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find("\"bytes_streamed\""), std::string::npos) << text;
    EXPECT_NE(text.find("\"parking_rounds\""), std::string::npos) << text;
    expectError(run("render " + model + " -o " + budgeted + " --geometry-budget -1"), {"--geometry-budget", "MiB"});
    expectError(run("render " + model + " -o " + budgeted + " --geometry-budget 0.001"), {"--geometry-budget", "holds no page"});
    expectError(run("render " + model + " -o " + budgeted + " --geometry-budget 1 --cull none"), {"--geometry-budget", "--cull none"});
}

TEST(Cli, RenderWithSceneFileAndLightsOnTheCommandLine)
{
    std::string model = tmp("plant.ply"), scene = tmp("scene.json"), image = tmp("scene.png");
    ASSERT_EQ(run("generate plant --triangles 20000 -o " + model).status, 0);
    std::ofstream(scene) << R"({"model": "cli_plant.ply", "camera": {"position": [30, 25, 30], "target": [0, 0, 0], "fov": 50},
        "lights": [{"type": "spot", "position": [5, 30, 5], "direction": [0, -1, 0], "outer_cone": 50, "intensity": 900}]})";
    Result result = run("render --scene " + scene + " -o " + image + " --size 128 --validation");
    EXPECT_EQ(result.status, 0) << result.output;
    EXPECT_TRUE(fs::exists(image));
    result = run("render " + model + " -o " + tmp("lights.png") +
                 " --size 128 --validation --light 'point position=0,20,0 intensity=400' --light 'directional direction=1,-2,1'");
    EXPECT_EQ(result.status, 0) << result.output;
    EXPECT_NE(result.output.find("lights 2"), std::string::npos) << result.output;
}

TEST(Cli, PreprocessInfoAndRenderAPenumbraFile)
{
    std::string input = tmp("scan_pp.ply"), model = tmp("scan_pp.penumbra"), image = tmp("scan_pp.png");
    ASSERT_EQ(run("generate scan --triangles 40000 -o " + input).status, 0);
    Result preprocessed = run("preprocess " + input + " -o " + model + " --quiet");
    ASSERT_EQ(preprocessed.status, 0) << preprocessed.output;
    EXPECT_NE(preprocessed.output.find("B/tri"), std::string::npos) << preprocessed.output;

    Result info = run("info " + model);
    ASSERT_EQ(info.status, 0) << info.output;
    for (const char* field : {"triangles", "clusters", "BVH", "depth", "max error", "vertices", "indices", "B/tri", "build"})
        EXPECT_NE(info.output.find(field), std::string::npos) << field << " missing in:\n" << info.output;

    Result rendered = run("render " + model + " -o " + image + " --size 128 --validation");
    EXPECT_EQ(rendered.status, 0) << rendered.output;
    EXPECT_TRUE(fs::exists(image));
}

TEST(Cli, PreprocessWritesOneFilePerSimplificationLevel)
{
    std::string input = tmp("levels.ply");
    ASSERT_EQ(run("generate scan --triangles 40000 -o " + input).status, 0);
    Result result = run("preprocess " + input + " -o " + tmp("levels.penumbra") + " --simplify 1,0.5,0.25 --quiet");
    ASSERT_EQ(result.status, 0) << result.output;
    for (const char* level : {"1", "0.5", "0.25"}) {
        std::string path = tmp(std::string("levels.") + level + ".penumbra");
        ASSERT_TRUE(fs::exists(path)) << path;
        Result info = run("info " + path);
        EXPECT_EQ(info.status, 0) << info.output;
        EXPECT_NE(info.output.find(std::string("simplify target ") + level), std::string::npos) << info.output;
    }
    EXPECT_GT(fs::file_size(tmp("levels.1.penumbra")), fs::file_size(tmp("levels.0.25.penumbra")) * 3);
}

TEST(Cli, BadModelFilesAndPreprocessOptions)
{
    std::string input = tmp("bad_pp.ply"), model = tmp("bad_pp.penumbra"), image = tmp("bad_pp.png");
    ASSERT_EQ(run("generate plant --triangles 20000 -o " + input).status, 0);
    ASSERT_EQ(run("preprocess " + input + " -o " + model + " --quiet").status, 0);
    std::string truncated = tmp("truncated_pp.penumbra");
    fs::copy_file(model, truncated, fs::copy_options::overwrite_existing);
    fs::resize_file(truncated, fs::file_size(model) - 100);
    expectError(run("render " + truncated + " -o " + image), {"truncated_pp.penumbra"});
    expectError(run("info " + truncated), {"truncated_pp.penumbra"});
    expectError(run("info " + input), {"bad_pp.ply"});
    expectError(run("preprocess " + input + " -o " + tmp("out.ply")), {"out.ply", ".penumbra"});
    expectError(run("preprocess " + input + " -o " + tmp("x.penumbra") + " --simplify 0"), {"--simplify"});
    expectError(run("preprocess " + tmp("missing_input.obj") + " -o " + tmp("y.penumbra")), {"missing_input.obj"});
    EXPECT_FALSE(fs::exists(image));
    EXPECT_FALSE(fs::exists(tmp("x.penumbra")));
}

TEST(Cli, BadInputGetsOneClearLineAndNoImage)
{
    std::string image = tmp("never.png");
    fs::remove(image);

    expectError(run("render " + tmp("does_not_exist.ply") + " -o " + image), {"does_not_exist.ply"});

    std::string truncated = tmp("truncated.ply");
    ASSERT_EQ(run("generate scan --triangles 5000 -o " + truncated).status, 0);
    fs::resize_file(truncated, fs::file_size(truncated) / 2);
    expectError(run("render " + truncated + " -o " + image), {"truncated.ply"});

    std::string garbage = tmp("garbage.glb");
    std::ofstream(garbage) << "this is not a model";
    expectError(run("render " + garbage + " -o " + image), {"garbage.glb"});

    std::string unknown = tmp("model.xyz");
    std::ofstream(unknown) << "1 2 3";
    expectError(run("render " + unknown + " -o " + image), {"model.xyz"});

    std::string badScene = tmp("bad.json");
    std::ofstream(badScene) << R"({"lights": [{"type": "laser"}]})";
    expectError(run("render --scene " + badScene + " -o " + image), {"bad.json", "laser"});

    expectError(run("render --size 0 -o " + image), {"--size"});
    expectError(run("render --shadows magic -o " + image), {"--shadows", "magic"});
    expectError(run("render --cull some -o " + image), {"--cull", "some"});
    expectError(run("render --light 'point position=1,2' -o " + image), {"--light"});
    expectError(run("render --device no-such-gpu -o " + image), {"no-such-gpu"});
    expectError(run("render -o " + tmp("image.unknownformat") + " --size 32"), {"image.unknownformat"});
    expectError(run("generate volcano -o " + tmp("volcano.ply")), {"volcano"});
    expectError(run("generate city -o " + tmp("city.nope")), {"city.nope"});

    EXPECT_FALSE(fs::exists(image));
}

// Files in a folder (names only), to see that a run left nothing behind.
std::vector<std::string> filesIn(const std::string& folder)
{
    std::vector<std::string> names;
    for (const fs::directory_entry& entry : fs::directory_iterator(folder))
        names.push_back(entry.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
}

std::string freshFolder(const std::string& name)
{
    std::string folder = tmp(name);
    fs::remove_all(folder);
    fs::create_directories(folder);
    return folder;
}

TEST(Cli, OptionRangeErrorsAreOneLineWithStatusOne)
{
    std::string image = tmp("range.png");
    fs::remove(image);
    expectError(run("render --shadow-map-size 5 -o " + image), {"--shadow-map-size"});
    expectError(run("render --samples 1000 -o " + image), {"--samples"});
    expectError(run("render --frames 0 -o " + image), {"--frames"});
    expectError(run("render --penumbra-maps 3 -o " + image), {"--penumbra-maps"});
    expectError(run("render --tonemap sepia -o " + image), {"--tonemap"});
    expectError(run("render --no-such-option -o " + image), {"--no-such-option"});
    expectError(run("render --size"), {"--size"});
    expectError(run("preprocess " + tmp("a.ply")), {"--output"});
    expectError(run("preprocess " + tmp("a.ply") + " -o " + tmp("a.penumbra") + " --cluster-vertices 300"), {"--cluster-vertices"});
    expectError(run("bench smoke --size 2"), {"--size"});
    expectError(run("bench nonsuite"), {"nonsuite"});
    expectError(run(""), {"subcommand"});
    EXPECT_FALSE(fs::exists(image));
}

// The output's folder and extension are checked before the model is read or
// the device created: with a missing model and a missing device as well, the
// error names the output.
TEST(Cli, OutputPathIsCheckedBeforeTheModelAndTheDevice)
{
    const std::string missingModel = tmp("no_such_model.ply");
    const std::string noFolder = tmp("no_such_folder") + "/out";
    fs::remove_all(tmp("no_such_folder"));
    expectError(run("render " + missingModel + " --device no-such-gpu -o " + noFolder + ".png"),
                {"out.png", "does not exist"});
    expectError(run("render " + missingModel + " --device no-such-gpu -o " + tmp("out.unknownformat")), {"out.unknownformat"});
    const std::string folder = freshFolder("output_is_a_folder.png");
    expectError(run("render " + missingModel + " --device no-such-gpu -o " + folder), {"output_is_a_folder.png", "folder"});
    expectError(run("render " + missingModel + " -o " + tmp("ok.png") + " --compare " + noFolder + ".png"), {"out.png", "does not exist"});
    expectError(run("render " + missingModel + " -o " + tmp("ok.png") + " --stats " + noFolder + ".json"), {"out.json", "does not exist"});
    expectError(run("preprocess " + missingModel + " -o " + noFolder + ".penumbra"), {"out.penumbra", "does not exist"});
    expectError(run("generate city --triangles 1000 -o " + noFolder + ".ply"), {"out.ply", "does not exist"});
    EXPECT_FALSE(fs::exists(tmp("ok.png")));
}

TEST(Cli, StatsAndImageAreRenamedIntoPlaceLeavingNothingElse)
{
    const std::string model = tmp("outputs_city.glb");
    ASSERT_EQ(run("generate city --triangles 5000 -o " + model).status, 0);
    const std::string folder = freshFolder("outputs");
    Result result = run("render " + model + " -o " + folder + "/image.png --size 64 --stats " + folder + "/stats.json --compare " + folder +
                        "/strip.png --validation");
    ASSERT_EQ(result.status, 0) << result.output;
    EXPECT_EQ(filesIn(folder), (std::vector<std::string>{"image.png", "stats.json", "strip.png"}));
    std::ifstream json(folder + "/stats.json");
    std::string text((std::istreambuf_iterator<char>(json)), std::istreambuf_iterator<char>());
    EXPECT_EQ(text.front(), '{');
    EXPECT_EQ(text.substr(text.size() - 2), "}\n");
}

// The .penumbra file's data reaches the disk before the rename makes it visible, and the rename
// itself after (the folder). strace shows the calls; skipped where strace is not installed.
TEST(Cli, PreprocessSyncsTheModelAroundTheRename)
{
    if (std::system("command -v strace > /dev/null 2>&1") != 0)
        GTEST_SKIP() << "strace is not installed";
    const std::string input = tmp("sync.ply"), model = tmp("sync.penumbra"), trace = tmp("sync.strace");
    ASSERT_EQ(run("generate scan --triangles 2000 -o " + input).status, 0);
    Result result = run("preprocess " + input + " -o " + model + " --quiet",
                        "strace -f -e trace=fsync,rename,renameat,renameat2 -o " + trace);
    ASSERT_EQ(result.status, 0) << result.output;
    std::ifstream log(trace);
    std::vector<std::string> calls;
    for (std::string line; std::getline(log, line);)
        for (const char* call : {"fsync(", "rename"})
            if (line.find(call) != std::string::npos && line.find("exited") == std::string::npos)
                calls.push_back(call);
    EXPECT_EQ(calls, (std::vector<std::string>{"fsync(", "rename", "fsync("}));
}

// Injected device faults (PENUMBRA_FAULT, runtime/src/device.h) end the run with one error line,
// exit status 1, and no output file; ctest's PENUMBRA_VALIDATION=1 would add a line for any leaked object.
TEST(Cli, DeviceFaultsGiveOneLineAndNoOutput)
{
    const std::string model = tmp("fault_scan.ply");
    ASSERT_EQ(run("generate scan --triangles 5000 -o " + model).status, 0);
    const std::string folder = freshFolder("faults");
    const std::string outputs = " -o " + folder + "/image.png --stats " + folder + "/stats.json --size 64 --shadows srt";
    expectError(run("render " + model + outputs, "PENUMBRA_FAULT=allocate:30"), {"out of device memory (VK_ERROR_OUT_OF_DEVICE_MEMORY)"});
    expectError(run("render " + model + outputs, "PENUMBRA_FAULT=submit:2"), {"device lost (VK_ERROR_DEVICE_LOST)"});
    expectError(run("render " + model + outputs, "PENUMBRA_FAULT=wait:3"), {"device did not finish", "shade"});
    EXPECT_EQ(filesIn(folder), std::vector<std::string>{});
}

// A validation message fails the run before anything is written.
TEST(Cli, AValidationMessageWritesNoImage)
{
    const std::string model = tmp("validation_scan.ply");
    ASSERT_EQ(run("generate scan --triangles 5000 -o " + model).status, 0);
    const std::string folder = freshFolder("validation");
    Result result = run("render " + model + " --validation -o " + folder + "/image.png --stats " + folder + "/stats.json --compare " +
                            folder + "/strip.png --size 64",
                        "PENUMBRA_FAULT=validation:2");
    EXPECT_EQ(result.status, 1) << result.output;
    EXPECT_NE(result.output.find("penumbra: validation error: injected by PENUMBRA_FAULT"), std::string::npos) << result.output;
    EXPECT_NE(result.output.find("penumbra: error: validation: 1 Vulkan validation message(s)"), std::string::npos) << result.output;
    EXPECT_EQ(filesIn(folder), std::vector<std::string>{});
}

} // namespace
