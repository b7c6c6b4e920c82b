// Fuzz target: the coupler's message decoder (docs/protocol.md). Input: byte 0 = number of frames
// (1–16), then per frame a little-endian u16 length and its bytes; what is left is the last frame.
// Decoded twice with a field memory, so `update:` fields meet a previous message. Any outcome but a
// decoded message or a cosim::protocol::ProtocolError is a finding.
#include <cstdint>
#include <cstring>

#include "cosim/protocol.hpp"

namespace pr = cosim::protocol;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::size_t frames = 1 + data[0] % 16;
  std::size_t at = 1;
  zmq::multipart_t message;
  for (std::size_t f = 0; f < frames && at <= size; ++f) {
    std::size_t length = size - at;
    if (f + 1 < frames && at + 2 <= size) {
      std::uint16_t l;
      std::memcpy(&l, data + at, 2);
      at += 2;
      length = std::min<std::size_t>(l, size - at);
    }
    message.addmem(data + at, length);
    at += length;
  }
  pr::FieldMemory memory;
  for (int pass = 0; pass < 2; ++pass) {
    zmq::multipart_t copy = message.clone();
    try {
      (void)pr::peekVersion(copy);
      pr::Message m = pr::decode(copy, "fuzz", &memory);
      (void)pr::encode(std::move(m), pr::kAllFeatures, &memory);
    } catch (const pr::ProtocolError&) {
    }
  }
  return 0;
}
