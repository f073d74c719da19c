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

} // namespace penumbra
