#include "lattice/rod_law.hpp"

#include <cmath>
#include <stdexcept>

#include <Eigen/Geometry>

#include "common/registry.hpp"
#include "rod_laws/beam.hpp"
#include "rod_laws/truss.hpp"

namespace lattice {

Mat12 rodStiffness(const Eigen::Vector3d& axis, double length, const RodSprings& s) {
  using Vec3 = Eigen::Vector3d;
  const Vec3 e1 = axis.normalized();
  const Vec3 e2 = (std::abs(e1.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(e1).normalized();
  const Vec3 e3 = e1.cross(e2);
  const double L = length;
  // The six measures Δ·e1, Δ·e2, Δ·e3, Φ·e1, Φ·e2, Φ·e3 with (θ × e1)·e2 = θ·e3, (θ × e1)·e3 = −θ·e2.
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
  D << s.normal, s.shear, s.shear, s.torsion, s.bending, s.bending;
  return B.transpose() * D.asDiagonal() * B;
}

Mat12 RodLaw::stiffness(const Eigen::Vector3d& axis, double length, const RelativeStiffness& k,
                        const RodSection& section) const {
  return rodStiffness(axis, length, springs(length, k, section));
}

namespace {
struct Entry {
  const char* name;
  std::unique_ptr<RodLaw> (*make)();
};
const Entry kRodLaws[] = {
    {"beam", []() -> std::unique_ptr<RodLaw> { return std::make_unique<Beam>(); }},
    {"truss", []() -> std::unique_ptr<RodLaw> { return std::make_unique<Truss>(); }},
};
constexpr common::Registry<Entry> kRegistry{kRodLaws, "rod law"};
}  // namespace

std::unique_ptr<RodLaw> makeRodLaw(const std::string& name) { return kRegistry.at(name).make(); }

const std::vector<std::string>& rodLawNames() {
  static const std::vector<std::string> names = kRegistry.names();
  return names;
}

}  // namespace lattice
