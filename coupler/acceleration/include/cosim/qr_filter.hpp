#pragma once
// The QR factorisation of IQN-ILS's least-squares matrix V with its filter (Haelterman et al. 2016): V's
// nearly dependent columns would make the least-squares problem ill-posed, so some are dropped.
//   qr2: modified Gram–Schmidt over the columns in order (newest first), dropping a column whose part
//        orthogonal to those kept is below `limit` times its own length (preCICE's QR2).
//   qr1: the factorisation of every column, then the first column with |R_ii| < limit ‖R‖_F dropped and
//        the factorisation repeated, until none is (preCICE's QR1).
// An exactly zero column is dropped by both.

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace cosim {

enum class QrFilter { kQr1, kQr2 };

/// QrFilter from its scene name ("qr1", "qr2"); std::invalid_argument otherwise.
QrFilter qrFilterNamed(const std::string& name);
std::vector<std::string> qrFilterNames();

/// Factorises the columns `column(i, v)` writes into v (i < count, each of length n), filtered. Returns
/// the indices of the kept columns in order; Q's first kept.size() columns (it may hold more: it is a
/// workspace that only grows) and R (kept × kept, upper triangular) are theirs.
std::vector<std::size_t> filteredQr(std::size_t count, Eigen::Index n,
                                    const std::function<void(std::size_t, Eigen::VectorXd&)>& column, QrFilter filter,
                                    double limit, Eigen::MatrixXd& Q, Eigen::MatrixXd& R);

}  // namespace cosim
