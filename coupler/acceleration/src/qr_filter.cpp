#include "cosim/qr_filter.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace cosim {

QrFilter qrFilterNamed(const std::string& name) {
  if (name == "qr1") return QrFilter::kQr1;
  if (name == "qr2") return QrFilter::kQr2;
  throw std::invalid_argument("unknown QR filter \"" + name + "\" (qr1, qr2)");
}

std::vector<std::string> qrFilterNames() { return {"qr1", "qr2"}; }

namespace {
// Modified Gram–Schmidt of the columns `which` into Q's first columns; a column whose orthogonal part is
// below `drop` times its length is left out (drop 0: only exactly dependent ones). Returns the kept ones.
// Q only grows: a pass of IQN-ILS over a large interface would otherwise allocate (and the kernel zero)
// a fresh n × k block whenever the column count changes, which it does at nearly every pass.
std::vector<std::size_t> gramSchmidt(const std::vector<std::size_t>& which, Eigen::Index n,
                                     const std::function<void(std::size_t, Eigen::VectorXd&)>& column, double drop,
                                     Eigen::MatrixXd& Q, Eigen::MatrixXd& R) {
  const auto m = static_cast<Eigen::Index>(which.size());
  if (Q.rows() != n || Q.cols() < m) Q.resize(n, std::max<Eigen::Index>(m, Q.rows() == n ? Q.cols() : 0));
  R.setZero(m, m);
  std::vector<std::size_t> kept;
  Eigen::VectorXd v(n);
  Eigen::Index k = 0;
  for (std::size_t i : which) {
    column(i, v);
    const double norm0 = v.norm();
    if (norm0 == 0.0) continue;
    for (Eigen::Index j = 0; j < k; ++j) {
      R(j, k) = Q.col(j).dot(v);
      v -= R(j, k) * Q.col(j);
    }
    const double rkk = v.norm();
    if (rkk < drop * norm0 || rkk == 0.0) {
      R.col(k).setZero();
      continue;
    }
    R(k, k) = rkk;
    Q.col(k) = v / rkk;
    kept.push_back(i);
    ++k;
  }
  R.conservativeResize(k, k);
  return kept;
}
}  // namespace

std::vector<std::size_t> filteredQr(std::size_t count, Eigen::Index n,
                                    const std::function<void(std::size_t, Eigen::VectorXd&)>& column, QrFilter filter,
                                    double limit, Eigen::MatrixXd& Q, Eigen::MatrixXd& R) {
  std::vector<std::size_t> all(count);
  for (std::size_t i = 0; i < count; ++i) all[i] = i;
  if (filter == QrFilter::kQr2) return gramSchmidt(all, n, column, limit, Q, R);
  std::vector<std::size_t> kept = gramSchmidt(all, n, column, 0.0, Q, R);
  while (true) {
    const double scale = R.norm();
    Eigen::Index bad = -1;
    for (Eigen::Index i = 0; i < R.rows() && bad < 0; ++i)
      if (std::abs(R(i, i)) < limit * scale) bad = i;
    if (bad < 0) return kept;
    kept.erase(kept.begin() + bad);
    kept = gramSchmidt(kept, n, column, 0.0, Q, R);
  }
}

}  // namespace cosim
