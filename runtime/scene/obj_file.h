// Wavefront OBJ geometry for triangle meshes: vertices (`v x y z`) and faces (`f a b c ...`,
// 1-based or negative indices, `a/t/n` forms; polygons fanned into triangles). Everything else
// in the file (normals, texture coordinates, groups, materials) is skipped.
#pragma once
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace cellphys::scene {

struct ObjMesh {
  std::vector<float> vertices;     // 3 floats a vertex
  std::vector<int32_t> triangles;  // 3 0-based vertex indices a triangle, in the file's winding
};

/// A bad OBJ file: the message names the line and what is wrong with it.
class ObjError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Parses OBJ text; `name` goes into messages ("level.obj:12: ...").
ObjMesh parse_obj(const std::string& text, const std::string& name);
/// Reads and parses an OBJ file.
ObjMesh load_obj(const std::string& path);

}  // namespace cellphys::scene
