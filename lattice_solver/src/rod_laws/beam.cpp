#include "beam.hpp"

#include <cmath>

#include <Eigen/Geometry>

namespace lattice {

Mat12 Beam::stiffness(const Eigen::Vector3d& axis, double length, const RelativeStiffness& k,
                      const RodSection& section) const {
  using Vec3 = Eigen::Vector3d;
  const Vec3 e1 = axis.normalized();
  // Any orthonormal e2, e3: both shear springs are equal and so are both bending springs, so K does
  // not depend on this choice.
  const Vec3 e2 = (std::abs(e1.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(e1).normalized();
  const Vec3 e3 = e1.cross(e2);
  const double L = length, A = section.area, E = section.youngModulus;
  // Relative motion at the midpoint c: Δ = u_b − u_a − (L/2)(θ_a + θ_b) × e1, Φ = θ_b − θ_a; the six
  // measures are Δ·e1, Δ·e2, Δ·e3, Φ·e1, Φ·e2, Φ·e3, with (θ × e1)·e2 = θ·e3, (θ × e1)·e3 = −θ·e2.
  Eigen::Matrix<double, 6, 12> B = Eigen::Matrix<double, 6, 12>::Zero();
  B.block<1, 3>(0, 0) = -e1.transpose();
  B.block<1, 3>(0, 6) = e1.transpose();
  B.block<1, 3>(1, 0) = -e2.transpose();
  B.block<1, 3>(1, 3) = -0.5 * L * e3.transpose();
  B.block<1, 3>(1, 6) = e2.transpose();
  B.block<1, 3>(1, 9) = -0.5 * L * e3.transpose();
  B.block<1, 3>(2, 0) = -e3.transpose();
  B.block<1, 3>(2, 3) = 0.5 * L * e2.transpose();
  B.block<1, 3>(2, 6) = e3.transpose();
  B.block<1, 3>(2, 9) = 0.5 * L * e2.transpose();
  for (int r = 0; r < 3; ++r) {
    const Vec3& e = r == 0 ? e1 : r == 1 ? e2 : e3;
    B.block<1, 3>(3 + r, 3) = -e.transpose();
    B.block<1, 3>(3 + r, 9) = e.transpose();
  }
  Eigen::Matrix<double, 6, 1> D;
  const double axial = E * A / L, rotational = E * A * A / L;
  D << k.kl * axial, k.kb * axial, k.kb * axial, k.kt * rotational / 6.0, k.kb * rotational / 12.0,
      k.kb * rotational / 12.0;
  return B.transpose() * D.asDiagonal() * B;
}

}  // namespace lattice
