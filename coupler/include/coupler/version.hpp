#pragma once
// Versions both sides of a coupled run compare at the handshake.
namespace coupler {
/// Wire protocol version; bump on any change to a message layout.
inline constexpr int kProtocolVersion = 15;
/// The project release both executables were built from.
const char* release_version();
}  // namespace coupler
