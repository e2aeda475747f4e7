// The global operator new of a test program that counts its allocations
// (support/allocation_counter.h).

#include "support/allocation_counter.h"

#include <cstdlib>
#include <new>

namespace calib::testing {

std::atomic<int64_t> g_allocations{0};

}  // namespace calib::testing

// GCC pairs the inlined free() below with `new` expressions elsewhere and
// warns of a mismatch; malloc/free are the matching pair here.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
void* operator new(std::size_t size) {
  ++calib::testing::g_allocations;
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
// The nothrow forms too (std::stable_sort's buffer uses them): else, where a
// sanitizer's runtime defines every form, its nothrow new would pair with
// the free() below (AddressSanitizer: alloc-dealloc-mismatch).
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  ++calib::testing::g_allocations;
  return std::malloc(size == 0 ? 1 : size);
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
#pragma GCC diagnostic pop
