// Cost of one coupling exchange against a raw ZeroMQ request–reply of the same payload (issue 5).
//
//   exchange_bench [--nodes 1000] [--exchanges 2000] [--rounds 7]
//
// A: the coupler side (ROUTER, protocol encode/decode as in cosim) sends ADVANCE with one 3-component
//    field on N nodes to a cosim::Participant in another thread (DEALER, its own ZeroMQ context, ipc),
//    which reads it, writes a field of the same size and completes: RESULT comes back.
// B: REQ/REP between two plain sockets over ipc with the same payload both ways, no header, no copies
//    beyond ZeroMQ's own.
// Rounds alternate A B A B …; the medians of the per-exchange times and their ratio are printed.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <zmq.hpp>

#include "cosim/participant.hpp"
#include "cosim/protocol.hpp"

namespace pr = cosim::protocol;
using Clock = std::chrono::steady_clock;

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// One round of `count` coupler → participant → coupler exchanges [s per exchange].
double protocolRound(const std::string& endpoint, std::size_t values, int count) {
  zmq::context_t ctx(1);
  zmq::socket_t router(ctx, zmq::socket_type::router);
  router.set(zmq::sockopt::linger, 0);
  router.bind(endpoint);
  std::thread peer([&] {
    cosim::Participant p("solver", endpoint);
    std::vector<double> nodes(values, 0.0);
    p.addMesh("interface", nodes, {});
    p.addRead("interface", "force", 3);
    p.addWrite("interface", "displacement", 3);
    p.initialize();
    cosim::Window w;
    std::vector<double> out(values);
    while (p.nextWindow(w)) {
      const auto f = p.read("interface", "force");
      std::copy(f.begin(), f.end(), out.begin());
      p.write("interface", "displacement", out);
      p.complete(0.0, 0.0);
    }
  });
  std::string peerId;  // the participant's connection (ZeroMQ's routing identity), from its HELLO
  auto receive = [&] {  // the participant's heartbeats (about once a second) are not answers
    while (true) {
      zmq::multipart_t frames;
      frames.recv(router);
      peerId = frames.popstr();
      pr::Message m = pr::decode(frames, "solver");
      if (m.header.type != pr::Type::kHeartbeat) return m;
    }
  };
  auto send = [&](const pr::Message& m) {
    zmq::multipart_t frames = pr::encode(m);
    frames.pushstr(peerId);
    frames.send(router);
  };
  receive();  // HELLO
  pr::Message welcome;
  welcome.header.type = pr::Type::kWelcome;
  welcome.header.dt = 1.0;
  welcome.header.value0 = 1e9;
  send(welcome);
  pr::Message advance;
  advance.header.type = pr::Type::kAdvance;
  advance.fields.push_back({"interface/force", std::vector<double>(values, 1.0)});
  double seconds = 0.0;
  for (int i = -20; i < count; ++i) {  // 20 warm-up exchanges
    const auto t0 = Clock::now();
    advance.header.window = static_cast<std::uint64_t>(i + 20);
    send(advance);
    pr::Message r = receive();
    if (r.fields.empty() || r.fields[0].data.size() != values) throw std::runtime_error("bad RESULT");
    if (i >= 0) seconds += std::chrono::duration<double>(Clock::now() - t0).count();
  }
  pr::Message fin;
  fin.header.type = pr::Type::kFinalize;
  send(fin);
  // The participant's BYE may be lost when its socket closes (linger 0) right after sending it, as the
  // coupler also allows: wait for it a bounded time only.
  (void)pr::receive(router, std::chrono::milliseconds(1000));
  peer.join();
  return seconds / count;
}

double rawRound(const std::string& endpoint, std::size_t values, int count) {
  zmq::context_t ctx(1);
  zmq::socket_t req(ctx, zmq::socket_type::req);
  req.set(zmq::sockopt::linger, 0);
  req.bind(endpoint);
  std::thread peer([&] {
    zmq::context_t c2(1);
    zmq::socket_t rep(c2, zmq::socket_type::rep);
    rep.set(zmq::sockopt::linger, 1000);  // the last reply must not be dropped when this context closes
    rep.connect(endpoint);
    std::vector<double> out(values);
    for (int i = -20; i < count; ++i) {
      zmq::message_t in;
      (void)rep.recv(in);
      std::memcpy(out.data(), in.data(), std::min(in.size(), values * sizeof(double)));
      rep.send(zmq::buffer(out), zmq::send_flags::none);
    }
  });
  std::vector<double> payload(values, 1.0);
  double seconds = 0.0;
  for (int i = -20; i < count; ++i) {
    const auto t0 = Clock::now();
    req.send(zmq::buffer(payload), zmq::send_flags::none);
    zmq::message_t reply;
    (void)req.recv(reply);
    if (reply.size() != values * sizeof(double)) throw std::runtime_error("bad reply");
    if (i >= 0) seconds += std::chrono::duration<double>(Clock::now() - t0).count();
  }
  peer.join();
  return seconds / count;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("exchange_bench: one coupling exchange against a raw ZeroMQ request-reply");
  int nodes = 1000, exchanges = 2000, rounds = 7;
  app.add_option("--nodes", nodes, "interface nodes (3 values each)")->check(CLI::PositiveNumber);
  app.add_option("--exchanges", exchanges, "exchanges per round")->check(CLI::PositiveNumber);
  app.add_option("--rounds", rounds, "rounds of each kind, alternating")->check(CLI::PositiveNumber);
  CLI11_PARSE(app, argc, argv);
  const auto dir = std::filesystem::temp_directory_path() / fmt::format("cosim_xbench_{}", ::getpid());
  std::filesystem::create_directories(dir);
  const std::size_t values = 3 * static_cast<std::size_t>(nodes);
  std::vector<double> a, b;
  for (int r = 0; r < rounds; ++r) {
    a.push_back(protocolRound(fmt::format("ipc://{}/a{}.sock", dir.string(), r), values, exchanges));
    b.push_back(rawRound(fmt::format("ipc://{}/b{}.sock", dir.string(), r), values, exchanges));
  }
  std::filesystem::remove_all(dir);
  const double ma = median(a), mb = median(b);
  fmt::print("exchange of {} nodes ({} KiB each way), {} exchanges × {} rounds, medians:\n", nodes,
             values * sizeof(double) / 1024, exchanges, rounds);
  fmt::print("  cosim protocol (coupler ROUTER ↔ cosim::Participant): {:.1f} µs\n", ma * 1e6);
  fmt::print("  raw ZeroMQ REQ/REP:                                   {:.1f} µs\n", mb * 1e6);
  fmt::print("  ratio: {:.2f} (target ≤ 1.5)\n", ma / mb);
  return 0;
}
