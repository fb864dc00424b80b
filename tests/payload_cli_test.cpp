// Filled by the payload work (issue 29).
#include <gtest/gtest.h>
