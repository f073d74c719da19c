// Small helpers shared by the stand-alone bench programs (bench_budget,
// bench_cull, bench_raster, bench_rh): the median of a run's timings and a
// comma-separated option value.
#pragma once

#include <algorithm>
#include <sstream>
#include <string>
#include <vector>

namespace penumbra::bench_tool {

// The upper median of v (the middle element of an odd count); 0 for none.
inline double median(std::vector<double> v)
{
    if (v.empty())
        return 0.0;
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
}

// "a,b,c" -> {"a", "b", "c"}.
inline std::vector<std::string> splitCommas(const std::string& text)
{
    std::vector<std::string> out;
    std::stringstream stream(text);
    for (std::string item; std::getline(stream, item, ',');)
        out.push_back(item);
    return out;
}

} // namespace penumbra::bench_tool
