#include "truss.hpp"

namespace lattice {

Mat12 Truss::stiffness(const Eigen::Vector3d& axis, double length, const RelativeStiffness& k,
                       const RodSection& section) const {
  const Eigen::Vector3d e = axis.normalized();
  const Eigen::Matrix3d kee = k.kl * section.youngModulus * section.area / length * e * e.transpose();
  Mat12 K = Mat12::Zero();
  K.block<3, 3>(0, 0) = kee;
  K.block<3, 3>(6, 6) = kee;
  K.block<3, 3>(0, 6) = -kee;
  K.block<3, 3>(6, 0) = -kee;
  return K;
}

}  // namespace lattice
