// What the plain firmware-style test programs share (no gtest): they must be compiled as the agent
// is, with -fno-exceptions -fno-rtti, and CHECK(cond) ends main() with 1 and the failed condition.
#pragma once

#include <cstdio>

#if defined(__cpp_exceptions) || defined(__EXCEPTIONS)
#error "this file must be compiled with -fno-exceptions"
#endif
#if defined(__cpp_rtti) || defined(__GXX_RTTI)
#error "this file must be compiled with -fno-rtti"
#endif

#define CHECK(cond)                                                                  \
  do {                                                                               \
    if (!(cond)) {                                                                   \
      std::fprintf(stderr, "%s:%d: check failed: %s\n", __FILE__, __LINE__, #cond); \
      return 1;                                                                      \
    }                                                                                \
  } while (0)
