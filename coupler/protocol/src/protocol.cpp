#include "cosim/protocol.hpp"

#include <cmath>
#include <cstring>

#include <fmt/format.h>

namespace cosim::protocol {

const char* toString(Type t) {
  switch (t) {
    case Type::kHello: return "HELLO";
    case Type::kWelcome: return "WELCOME";
    case Type::kAdvance: return "ADVANCE";
    case Type::kResult: return "RESULT";
    case Type::kFinalize: return "FINALIZE";
    case Type::kError: return "ERROR";
    case Type::kHeartbeat: return "HEARTBEAT";
    case Type::kBye: return "BYE";
  }
  return "?";
}

const Field* Message::field(const std::string& name) const {
  for (const auto& f : fields)
    if (f.name == name) return &f;
  return nullptr;
}

namespace {
template <class T>
void put(unsigned char* buf, std::size_t offset, T v) {
  std::memcpy(buf + offset, &v, sizeof(T));
}
template <class T>
T get(const unsigned char* buf, std::size_t offset) {
  T v;
  std::memcpy(&v, buf + offset, sizeof(T));
  return v;
}
}  // namespace

zmq::multipart_t encode(const Message& m) {
  unsigned char h[kHeaderSize] = {};
  put(h, 0, kMagic);
  put(h, 4, kVersion);
  put(h, 6, static_cast<std::uint16_t>(m.header.type));
  put(h, 8, m.header.window);
  put(h, 16, m.header.iteration);
  put(h, 20, m.header.flags);
  put(h, 24, m.header.time);
  put(h, 32, m.header.dt);
  put(h, 40, m.header.value0);
  put(h, 48, m.header.value1);
  put(h, 56, static_cast<std::uint32_t>(m.header.type == Type::kError ? 0 : m.fields.size()));
  zmq::multipart_t out;
  out.addmem(h, kHeaderSize);
  if (m.header.type == Type::kError) {
    out.addstr(m.text);
    return out;
  }
  for (const auto& f : m.fields) {
    out.addstr(f.name);
    out.addmem(f.data.data(), f.data.size() * sizeof(double));
  }
  return out;
}

Message decode(zmq::multipart_t& frames, const std::string& from) {
  if (frames.empty()) throw ProtocolError(fmt::format("empty message from {}", from));
  zmq::message_t head = frames.pop();
  if (head.size() != kHeaderSize)
    throw ProtocolError(fmt::format("message from {} has a {}-byte header, expected {}", from, head.size(), kHeaderSize));
  const auto* h = static_cast<const unsigned char*>(head.data());
  if (get<std::uint32_t>(h, 0) != kMagic)
    throw ProtocolError(fmt::format("message from {} is not a cosim message (bad magic)", from));
  const auto version = get<std::uint16_t>(h, 4);
  if (version != kVersion)
    throw ProtocolError(fmt::format("{} speaks protocol version {}, this coupler speaks version {}", from, version, kVersion));
  Message m;
  m.header.type = static_cast<Type>(get<std::uint16_t>(h, 6));
  m.header.window = get<std::uint64_t>(h, 8);
  m.header.iteration = get<std::uint32_t>(h, 16);
  m.header.flags = get<std::uint32_t>(h, 20);
  m.header.time = get<double>(h, 24);
  m.header.dt = get<double>(h, 32);
  m.header.value0 = get<double>(h, 40);
  m.header.value1 = get<double>(h, 48);
  m.header.fieldCount = get<std::uint32_t>(h, 56);
  if (m.header.type < Type::kHello || m.header.type > Type::kBye)
    throw ProtocolError(fmt::format("message from {} has unknown type {}", from, static_cast<int>(m.header.type)));
  if (m.header.type == Type::kError) {
    m.text = frames.empty() ? std::string("(no text)") : frames.popstr();
    return m;
  }
  if (frames.size() != 2 * static_cast<std::size_t>(m.header.fieldCount))
    throw ProtocolError(fmt::format("{} from {} declares {} fields but carries {} frames after the header",
                                    toString(m.header.type), from, m.header.fieldCount, frames.size()));
  for (std::uint32_t i = 0; i < m.header.fieldCount; ++i) {
    Field f;
    f.name = frames.popstr();
    zmq::message_t data = frames.pop();
    if (data.size() % sizeof(double) != 0)
      throw ProtocolError(fmt::format("field \"{}\" from {} has {} bytes, not a whole number of float64", f.name, from,
                                      data.size()));
    f.data.resize(data.size() / sizeof(double));
    std::memcpy(f.data.data(), data.data(), data.size());
    for (std::size_t k = 0; k < f.data.size(); ++k)
      if (!std::isfinite(f.data[k]))
        throw ProtocolError(fmt::format("field \"{}\" from {} holds a non-finite value at index {}", f.name, from, k));
    m.fields.push_back(std::move(f));
  }
  return m;
}

std::optional<zmq::multipart_t> receive(zmq::socket_t& socket, std::chrono::milliseconds timeout) {
  zmq::pollitem_t item{socket.handle(), 0, ZMQ_POLLIN, 0};
  if (zmq::poll(&item, 1, timeout) <= 0) return std::nullopt;
  zmq::multipart_t m;
  if (!m.recv(socket)) return std::nullopt;
  return m;
}

}  // namespace cosim::protocol
