// penumbra-preprocess: the model tools of `penumbra` (preprocess, merge,
// generate, info) without the renderer, so it links neither Vulkan nor the
// image libraries. Its process baseline is a few MiB (penumbra's is about
// 130 MiB of shared libraries), which matters for builds under a memory limit
// and on cluster nodes without a GPU stack (docs/slurm).
#include <cstdio>
#include <new>

#include "penumbra/error.h"
#include "penumbra/file_io.h"
#include "tool_commands.h"

int main(int argc, char** argv)
{
    using namespace penumbra;
    removeTemporariesOnSignals("penumbra-preprocess");
    CLI::App app{"penumbra-preprocess: the model tools of penumbra (preprocess, merge, generate, info), without the renderer"};
    app.require_subcommand(1);
    app.set_version_flag("--version", "penumbra-preprocess 0.1.0");
    ToolCommands tools;
    addToolCommands(app, tools);
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        if (e.get_exit_code() == 0)
            return app.exit(e);
        std::string message = e.what();
        for (char& c : message)
            if (c == '\n' || c == '\r')
                c = ' ';
        std::fprintf(stderr, "penumbra-preprocess: error: %s\n", message.c_str());
        return 1;
    }
    try {
        int rc = 0;
        runToolCommands(tools, rc);
        return rc;
    } catch (const Error& e) {
        std::fprintf(stderr, "penumbra-preprocess: error: %s\n", e.what());
    } catch (const std::bad_alloc&) {
        std::fprintf(stderr, "penumbra-preprocess: error: out of memory\n");
    } catch (const std::exception& e) {
        std::fprintf(stderr, "penumbra-preprocess: error: %s\n", e.what());
    }
    return 1;
}
