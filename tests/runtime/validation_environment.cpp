// Fails the test binary when any Vulkan validation message was seen (the
// layer is enabled for every test through PENUMBRA_VALIDATION=1 in ctest).
#include <gtest/gtest.h>

#include "penumbra/penumbra.h"

namespace {

class ValidationEnvironment : public ::testing::Environment {
public:
    void TearDown() override
    {
        EXPECT_EQ(penumbra::validationMessagesInProcess(), 0u) << "Vulkan validation messages were printed above";
    }
};

const auto* const registered = ::testing::AddGlobalTestEnvironment(new ValidationEnvironment);

} // namespace
