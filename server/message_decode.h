// The client side of the protocol: the server's messages read back into plain structs, as a
// C++ client would (the tests and the serving benchmark use it). Each decoder checks the
// header and that the counts fit the length, and returns "" or what is wrong.
#pragma once
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "runtime/ppe/body_state.h"
#include "server/protocol.h"

namespace cellphys::server {

struct JoinMessage {
  protocol::Join head{};
  std::string world;
  std::vector<protocol::ShapeRecord> shapes;
  // Per shape, empty but for hulls, meshes and height fields: the vertices (3 floats each),
  // face_start (faces + 1) and face_vertices (a mesh's or height field's triangles, 3 each).
  std::vector<std::vector<float>> vertices;
  std::vector<std::vector<uint32_t>> face_start, face_vertices;
  // Per shape, empty but for compounds (revision 4): the parts, each naming an earlier shape.
  std::vector<std::vector<protocol::CompoundPartRecord>> parts;
  std::vector<protocol::BodyFull> bodies;
};

struct TickMessage {
  protocol::Tick head{};
  std::vector<protocol::BodyFull> entered;
  std::vector<std::pair<uint32_t, ppe::BodyState>> moved;  // dequantised when quantised
  std::vector<uint32_t> gone;
};

struct ErrorMessage {
  protocol::Error head{};
  std::string field, reason;
};

struct StatusMessage {
  protocol::Status head{};
  std::string text;
};

struct DebugMessage {
  protocol::Debug head{};
  std::vector<protocol::DebugBody> bodies;
  std::vector<protocol::DebugContact> contacts;
  std::vector<protocol::DebugCut> cuts;  // revision 3
};

struct StagesMessage {
  protocol::Stages head{};
  std::vector<std::pair<std::string, float>> stages;  // name, ms, in the server's order
};

/// The message's type (0 if it has no whole header).
uint16_t message_type(const unsigned char* data, size_t size);

std::string decode_join(const unsigned char* data, size_t size, JoinMessage& out);
std::string decode_tick(const unsigned char* data, size_t size, TickMessage& out);
std::string decode_ack(const unsigned char* data, size_t size, protocol::Ack& out);
std::string decode_error(const unsigned char* data, size_t size, ErrorMessage& out);
std::string decode_status(const unsigned char* data, size_t size, StatusMessage& out);
std::string decode_stages(const unsigned char* data, size_t size, StagesMessage& out);
std::string decode_debug(const unsigned char* data, size_t size, DebugMessage& out);

}  // namespace cellphys::server
