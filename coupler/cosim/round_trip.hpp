#pragma once
// The raw ZeroMQ round trip of this machine at this moment: the yardstick for the coupling's own time
// per pass (the summary's `zmq_round_trip_s` beside `outside_solvers_per_pass_s`). A message of the
// size of the run's largest ADVANCE goes to a peer with its own context (its own I/O thread, as a
// participant process has) over the same kind of transport, and comes back unchanged; the median of
// `count` round trips. Nothing of the run is read or sent.

#include <cstddef>
#include <filesystem>
#include <string>

namespace cosim {

/// `endpoint`: the run's bound endpoint (its kind, ipc or tcp, is used); `dir`: where an ipc socket may
/// go. Returns the median round trip [s], or a negative value when the measurement could not be made.
double measureRoundTrip(const std::string& endpoint, const std::filesystem::path& dir, std::size_t bytes,
                        int count = 200);

}  // namespace cosim
