#include "round_trip.hpp"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <zmq.hpp>

namespace cosim {

double measureRoundTrip(const std::string& endpoint, const std::filesystem::path& dir, std::size_t bytes, int count) {
  try {
    zmq::context_t ours(1), theirs(1);
    zmq::socket_t a(ours, zmq::socket_type::pair);
    a.set(zmq::sockopt::linger, 0);
    a.set(zmq::sockopt::rcvtimeo, 1000);
    std::string where;
    if (endpoint.rfind("ipc://", 0) == 0) {
      where = fmt::format("ipc://{}/rtt-{}.sock", dir.string(), ::getpid());
      a.bind(where);
    } else {
      a.bind("tcp://127.0.0.1:*");
      where = a.get(zmq::sockopt::last_endpoint);
    }
    std::thread echo([&] {
      try {
        zmq::socket_t b(theirs, zmq::socket_type::pair);
        b.set(zmq::sockopt::linger, 0);
        b.set(zmq::sockopt::rcvtimeo, 1000);
        b.connect(where);
        for (int i = 0; i < count; ++i) {
          zmq::message_t m;
          if (!b.recv(m)) return;
          b.send(m, zmq::send_flags::none);
        }
      } catch (const zmq::error_t&) {
      }
    });
    std::vector<double> times;
    std::vector<char> payload(bytes, '\0');
    try {
      for (int i = 0; i < count; ++i) {
        const auto start = std::chrono::steady_clock::now();
        a.send(zmq::buffer(payload), zmq::send_flags::none);
        zmq::message_t back;
        if (!a.recv(back)) break;
        times.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
      }
    } catch (const zmq::error_t&) {
      times.clear();
    }
    echo.join();  // its receive times out within a second when no more comes
    if (where.rfind("ipc://", 0) == 0) std::filesystem::remove(where.substr(6));
    if (times.empty()) return -1.0;
    std::nth_element(times.begin(), times.begin() + static_cast<std::ptrdiff_t>(times.size() / 2), times.end());
    return times[times.size() / 2];
  } catch (const std::exception&) {
    return -1.0;
  }
}

}  // namespace cosim
