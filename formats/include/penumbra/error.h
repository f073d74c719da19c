// Errors raised for bad input: one line, naming the file (or option) and the problem.
#pragma once

#include <stdexcept>
#include <string>

namespace penumbra {

// Thrown for every user-facing failure (bad file, bad option, device trouble).
// what() is a single line "<subject>: <problem>" suitable for printing as is.
class Error : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// Throws Error("<subject>: <problem>"). subject is usually a file path.
[[noreturn]] inline void fail(const std::string& subject, const std::string& problem)
{
    throw Error(subject + ": " + problem);
}

// Non-fatal problems in the input (a feature that was skipped). A sink gets one
// line "<subject>: <problem>"; the default sink prints
// "penumbra: warning: <subject>: <problem>" to stderr. Importers report each
// kind of problem once per file (with a count), after the import succeeded.
using WarningSink = void (*)(const std::string& line);
// Installs sink (nullptr: the default) and returns the previous one.
WarningSink setWarningSink(WarningSink sink);
void warn(const std::string& subject, const std::string& problem);

} // namespace penumbra
