#pragma once
// A sum over bodies or contacts in a fixed order on any number of threads (the energy ledger's sums).
#include <omp.h>

#include <array>
#include <cstddef>
#include <vector>

#include "dem/contact_law.hpp"
#include "per_thread.hpp"

namespace dem::detail {

// Runs body(i, partial) for i < n over the OpenMP threads (static schedule) and adds the threads'
// partial sums into `total` in thread order. OpenMP's own `reduction(+)` combines them in whatever order
// the threads finish, so the energy ledger would differ in its last bits from run to run.
template <std::size_t N, class Body>
void orderedSum(std::ptrdiff_t n, std::array<double, N>& total, Body&& body) {
  const int nt = n > kParallelMin ? omp_get_max_threads() : 1;
  if (nt == 1) {  // no parallel region and no allocation: this runs several times per step
    std::array<double, N> mine{};
    for (std::ptrdiff_t i = 0; i < n; ++i) body(i, mine);
    for (std::size_t k = 0; k < N; ++k) total[k] += mine[k];
    return;
  }
  PerThread<std::array<double, N>> partial(static_cast<std::size_t>(nt), std::array<double, N>{});
#pragma omp parallel num_threads(nt)
  {
    // On the thread's stack, where the compiler may keep it in registers; stored once at the end.
    std::array<double, N> mine{};
#pragma omp for schedule(static)
    for (std::ptrdiff_t i = 0; i < n; ++i) body(i, mine);
    partial[static_cast<std::size_t>(omp_get_thread_num())] = mine;
  }
  partial.forEach([&](const std::array<double, N>& p) {
    for (std::size_t k = 0; k < N; ++k) total[k] += p[k];
  });
}


}  // namespace dem::detail
