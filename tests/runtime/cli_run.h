// Runs the penumbra CLI from the tests, and paths in the tests' scratch folder.
#pragma once

#include <cstdio>
#include <filesystem>
#include <string>
#include <sys/wait.h>

namespace penumbra::test {

// Runs `penumbra ARGUMENTS` (environment: "NAME=value ..." for this run only);
// returns the exit status (-1 when it did not exit) and, in output, stdout and stderr.
inline int runCli(const std::string& arguments, std::string* output = nullptr, const std::string& environment = "")
{
    std::string command = environment + " " + std::string(PENUMBRA_CLI) + " " + arguments + " 2>&1";
    FILE* pipe = popen(command.c_str(), "r");
    if (!pipe)
        return -1;
    char buffer[4096];
    std::string text;
    while (size_t n = fread(buffer, 1, sizeof(buffer), pipe))
        text.append(buffer, n);
    if (output)
        *output = text;
    int status = pclose(pipe);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// PENUMBRA_TEST_TMP/<prefix><name>, the folder made if needed.
inline std::string scratchPath(const std::string& prefix, const std::string& name)
{
    std::filesystem::create_directories(PENUMBRA_TEST_TMP);
    return std::string(PENUMBRA_TEST_TMP) + "/" + prefix + name;
}

} // namespace penumbra::test
