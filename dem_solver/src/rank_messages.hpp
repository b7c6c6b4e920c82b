#pragma once
// The messages of a run on several MPI ranks (dem/ranked_run.hpp): the reductions and exchanges that
// RankedSimulation and the run's output use, all over MPI_COMM_WORLD.
#include <mpi.h>

#include <numeric>
#include <string>
#include <vector>

#include "common/errors.hpp"

namespace dem::detail {

// Whether a failure now would be this rank's alone, the others waiting for it in a collective: then the
// run is aborted (stopRanks), not finalized, so that nothing hangs. Failures all ranks agree on (the
// scene's errors, the summed ledger's verdict, RankedSimulation's agreed instabilities) end every rank
// together.
inline bool alone = false;

inline double allReduce(double v, MPI_Op op) {
  MPI_Allreduce(MPI_IN_PLACE, &v, 1, MPI_DOUBLE, op, MPI_COMM_WORLD);
  return v;
}

// What `out[r]` holds goes to rank r; returns what came from every rank, in rank order. `expected`: how
// many values each rank sends here, when known (else they are exchanged first).
inline std::vector<double> allToAll(const std::vector<std::vector<double>>& out, const std::vector<int>* expected = nullptr) {
  const auto P = out.size();
  std::vector<int> sendCount(P), recvCount(P), sendAt(P, 0), recvAt(P, 0);
  for (std::size_t r = 0; r < P; ++r) sendCount[r] = static_cast<int>(out[r].size());
  if (expected) recvCount = *expected;
  else MPI_Alltoall(sendCount.data(), 1, MPI_INT, recvCount.data(), 1, MPI_INT, MPI_COMM_WORLD);
  std::partial_sum(sendCount.begin(), sendCount.end() - 1, sendAt.begin() + 1);
  std::partial_sum(recvCount.begin(), recvCount.end() - 1, recvAt.begin() + 1);
  std::vector<double> send, recv(static_cast<std::size_t>(recvAt.back() + recvCount.back()));
  send.reserve(static_cast<std::size_t>(sendAt.back() + sendCount.back()));
  for (const auto& o : out) send.insert(send.end(), o.begin(), o.end());
  MPI_Alltoallv(send.data(), sendCount.data(), sendAt.data(), MPI_DOUBLE, recv.data(), recvCount.data(),
                recvAt.data(), MPI_DOUBLE, MPI_COMM_WORLD);
  return recv;
}

// Every rank's `mine` at rank 0, in rank order (empty on the others).
inline std::vector<double> gatherAtRoot(const std::vector<double>& mine, int rank, int size) {
  int n = static_cast<int>(mine.size());
  std::vector<int> count(static_cast<std::size_t>(size)), at(static_cast<std::size_t>(size), 0);
  MPI_Gather(&n, 1, MPI_INT, count.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
  std::vector<double> all;
  if (rank == 0) {
    std::partial_sum(count.begin(), count.end() - 1, at.begin() + 1);
    all.resize(static_cast<std::size_t>(at.back() + count.back()));
  }
  MPI_Gatherv(mine.data(), n, MPI_DOUBLE, all.data(), count.data(), at.data(), MPI_DOUBLE, 0, MPI_COMM_WORLD);
  return all;
}

// Returns if no rank met an `error` in its input (empty: none); else throws, on every rank, the
// ConfigError of the lowest rank that did: what one rank finds wrong (its checkpoint file) ends all of
// them together, with exit 2.
inline void agreeOnInput(const std::string& error, int rank) {
  int size = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  const int first = static_cast<int>(allReduce(error.empty() ? size : rank, MPI_MIN));
  if (first == size) return;
  std::string text = rank == first ? error : std::string();
  int n = static_cast<int>(text.size());
  MPI_Bcast(&n, 1, MPI_INT, first, MPI_COMM_WORLD);
  text.resize(static_cast<std::size_t>(n));
  MPI_Bcast(text.data(), n, MPI_CHAR, first, MPI_COMM_WORLD);
  alone = false;
  throw common::ConfigError(text);
}

}  // namespace dem::detail
