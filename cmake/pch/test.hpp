// Precompiled for the tests (cmake/BuildSpeed.cmake): core.hpp and GoogleTest.
#include "core.hpp"
#ifdef __cplusplus
#include <gtest/gtest.h>
#endif
