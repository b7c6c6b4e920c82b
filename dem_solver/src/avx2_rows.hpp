#pragma once
// Four Vec3 at a time with AVX2 on their rows as they lie in memory, for the loops over bodies that
// GCC's own vectorisation of the stride-3 arrays handled element by element (the lone-sphere integrator,
// the neighbour list's displacement test). No FMA: the baseline loops must give the same bits.
#include "contact/batch_law.hpp"

#if defined(__x86_64__) && defined(__GNUC__)
namespace dem::detail {

// Four Vec3 rows held as they lie in memory (x0 y0 z0 x1 | y1 z1 x2 y2 | z2 x3 y3 z3) into x, y, z lanes.
[[gnu::always_inline]] DEM_TARGET_AVX2 inline void rowsToLanes(__m256d r0, __m256d r1, __m256d r2, __m256d& x,
                                                               __m256d& y, __m256d& z) {
  const __m256d m1 = _mm256_blend_pd(r0, r1, 0b1100);       // x0 y0 x2 y2
  const __m256d m2 = _mm256_permute2f128_pd(r0, r2, 0x21);  // z0 x1 z2 x3
  const __m256d m3 = _mm256_blend_pd(r1, r2, 0b1100);       // y1 z1 y3 z3
  x = _mm256_blend_pd(m1, m2, 0b1010);
  y = _mm256_shuffle_pd(m1, m3, 0b0101);
  z = _mm256_blend_pd(m2, m3, 0b1010);
}
[[gnu::always_inline]] DEM_TARGET_AVX2 inline __m256d vadd(__m256d a, __m256d b) { return _mm256_add_pd(a, b); }
[[gnu::always_inline]] DEM_TARGET_AVX2 inline __m256d vmul(__m256d a, __m256d b) { return _mm256_mul_pd(a, b); }
[[gnu::always_inline]] DEM_TARGET_AVX2 inline __m256d vdiv(__m256d a, __m256d b) { return _mm256_div_pd(a, b); }
// Four Vec3 (12 doubles at p) as three rows, and back.
[[gnu::always_inline]] DEM_TARGET_AVX2 inline void loadRows(const double* p, __m256d* r) {
  r[0] = _mm256_loadu_pd(p), r[1] = _mm256_loadu_pd(p + 4), r[2] = _mm256_loadu_pd(p + 8);
}
[[gnu::always_inline]] DEM_TARGET_AVX2 inline void storeRows(double* p, const __m256d* r) {
  _mm256_storeu_pd(p, r[0]), _mm256_storeu_pd(p + 4, r[1]), _mm256_storeu_pd(p + 8, r[2]);
}
// The dot products of four pairs of Vec3 rows (a·b per row, in the order (x + y) + z), one per lane.
[[gnu::always_inline]] DEM_TARGET_AVX2 inline __m256d rowDots(const __m256d* a, const __m256d* b) {
  __m256d x, y, z;
  rowsToLanes(vmul(a[0], b[0]), vmul(a[1], b[1]), vmul(a[2], b[2]), x, y, z);
  return vadd(vadd(x, y), z);
}

}  // namespace dem::detail
#endif
