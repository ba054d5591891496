/// @file count_new.hpp
/// @brief For a test binary that checks code allocates nothing: replaces the global operator
///        new/delete with malloc/free and counts every allocation in `g_news`. Include it in exactly
///        one translation unit of the binary (it defines the replacement functions).
#pragma once

#include <atomic>
#include <cstdlib>
#include <new>

// Replacing the global allocation functions with malloc/free is exactly what these tests want.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"

/// Allocations made so far by the test binary.
inline std::atomic<long> g_news{0};

void* operator new(std::size_t n) {
  g_news.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
