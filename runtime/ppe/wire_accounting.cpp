#include "runtime/ppe/wire_accounting.h"

#include "runtime/spu/island_image.h"

namespace cellphys::ppe {

using namespace cellphys::gen;

void count_wire_tables(const PackedIsland& p, const ShapeDictionary& shapes, StepStats& st) {
  const uint64_t n = p.bodies.size();
  const uint64_t shared = p.image.size() - n * sizeof(Rigid_Body);
  uint64_t geometry = 0;
  const spu::IslandView v = spu::view_island(const_cast<unsigned char*>(p.image.data()));
  for (uint64_t i = 0; i < n; ++i) geometry += shapes.bytes(v.bodies[i].shape_index);
  st.island_bodies += n;
  st.island_bytes_shared += shared;
  st.wire_table_to_nodes += n * sizeof(Wire_Body_To_Node) + geometry + shared;
  st.wire_table_to_nodes_compressed += n * sizeof(Wire_Body_To_Node_Compressed) + shared;
  st.wire_table_from_nodes += n * sizeof(Wire_Node_To_Dispatcher);
  st.image_bytes += p.image.size();
  st.result_bytes += p.result.size();
}

void add_wire_tables(const StepStats& part, StepStats& st) {
  st.island_bodies += part.island_bodies;
  st.island_bytes_shared += part.island_bytes_shared;
  st.wire_table_to_nodes += part.wire_table_to_nodes;
  st.wire_table_to_nodes_compressed += part.wire_table_to_nodes_compressed;
  st.wire_table_from_nodes += part.wire_table_from_nodes;
  st.image_bytes += part.image_bytes;
  st.result_bytes += part.result_bytes;
}

}  // namespace cellphys::ppe
