// The triaxial specimen generator (issue 27): radii drawn by number reproduce a sieve curve given by
// mass; the box holds them at the target porosity; the spheres are placed without overlap, inside it,
// the same for the same seed.
#include <cmath>

#include <gtest/gtest.h>

#include "dem/triaxial.hpp"

namespace {

dem::SpecimenSettings sieveSample(std::uint32_t count) {
  dem::SpecimenSettings s;
  s.count = count;
  s.sieve = {{1e-3, 0.0}, {2e-3, 0.5}, {3e-3, 1.0}};
  s.rmin = 1e-3, s.rmax = 3e-3;
  s.porosity = 0.4;
  s.seed = 7;
  return s;
}

}  // namespace

TEST(Specimen, RadiiFollowTheSieveCurveByMass) {
  const dem::Specimen s = dem::specimenRadii(sieveSample(200000));
  double total = 0.0, below = 0.0, belowHalf = 0.0;
  for (double r : s.radius) {
    const double m = r * r * r;
    total += m;
    if (r < 2e-3) below += m;
    if (r < 1.5e-3) belowHalf += m;
    ASSERT_GE(r, 1e-3);
    ASSERT_LE(r, 3e-3);
  }
  EXPECT_NEAR(below / total, 0.5, 0.005);
  EXPECT_NEAR(belowHalf / total, 0.25, 0.005);  // mass spread evenly over [1, 2] mm
  // The box holds the spheres at the porosity, in the proportions 1 : 1 : 2.
  double solid = 0.0;
  for (double r : s.radius) solid += 4.0 / 3.0 * M_PI * r * r * r;
  const dem::Vec3 size = s.hi - s.lo;
  EXPECT_NEAR(1.0 - solid / size.prod(), 0.4, 1e-12);
  EXPECT_NEAR(size.z() / size.x(), 2.0, 1e-12);
}

TEST(Specimen, PlacedWithoutOverlapInsideTheBoxAndReproducible) {
  dem::SpecimenSettings settings = sieveSample(2000);
  const double shrink = std::cbrt(0.25 / 0.6);
  const dem::Specimen a = dem::randomSpecimen(settings, shrink), b = dem::randomSpecimen(settings, shrink);
  ASSERT_EQ(a.centre.size(), 2000u);
  for (std::size_t i = 0; i < a.centre.size(); ++i) {
    EXPECT_EQ(a.centre[i], b.centre[i]);
    const double r = a.radius[i] * shrink;
    for (int k = 0; k < 3; ++k) {
      EXPECT_GE(a.centre[i][k] - r, a.lo[k]);
      EXPECT_LE(a.centre[i][k] + r, a.hi[k]);
    }
    for (std::size_t j = 0; j < i; ++j)
      ASSERT_GE((a.centre[i] - a.centre[j]).norm(), r + a.radius[j] * shrink) << i << " overlaps " << j;
  }
}
