# Regenerate the kernels whenever a descriptor, template or generator file changes.
# The build compiles from its own copy in the build tree; the checked-in generated/ is
# compared with a fresh generation by the codegen_drift test.
file(GLOB CELLPHYS_GEN_INPUTS CONFIGURE_DEPENDS
  ${PROJECT_SOURCE_DIR}/codegen/*.py
  ${PROJECT_SOURCE_DIR}/codegen/cellphys_codegen/*.py
  ${PROJECT_SOURCE_DIR}/codegen/descriptors/structs/*.yaml
  ${PROJECT_SOURCE_DIR}/codegen/descriptors/forces/*.yaml
  ${PROJECT_SOURCE_DIR}/examples/new_force/*.yaml
  ${PROJECT_SOURCE_DIR}/templates/*.j2
  ${PROJECT_SOURCE_DIR}/templates/util/*.jinja)

set(CELLPHYS_GEN_DIR ${PROJECT_BINARY_DIR}/generated)
set(CELLPHYS_GEN_STAMP ${CELLPHYS_GEN_DIR}/cellphys/gen/.stamp)
# The headers are byproducts, so the build knows the sources that include them must wait for
# a regeneration and be re-checked after it (force headers are named after their descriptor).
set(CELLPHYS_GEN_HEADERS)
foreach(name layouts.h layouts.json kernel_types.h force_table.h block_ops.h)
  list(APPEND CELLPHYS_GEN_HEADERS ${CELLPHYS_GEN_DIR}/cellphys/gen/${name})
endforeach()
foreach(yaml ${CELLPHYS_GEN_INPUTS})
  if(yaml MATCHES "/(descriptors/forces|examples/new_force)/([a-z0-9_]+)\\.yaml$")
    list(APPEND CELLPHYS_GEN_HEADERS ${CELLPHYS_GEN_DIR}/cellphys/gen/forces/${CMAKE_MATCH_2}.h)
  endif()
endforeach()
add_custom_command(
  OUTPUT ${CELLPHYS_GEN_STAMP}
  BYPRODUCTS ${CELLPHYS_GEN_HEADERS}
  COMMAND ${CELLPHYS_GENERATOR_PYTHON} ${PROJECT_SOURCE_DIR}/codegen/generate.py --out ${CELLPHYS_GEN_DIR}
  DEPENDS ${CELLPHYS_GEN_INPUTS}
  COMMENT "cellphys: generating kernels and layouts from descriptors"
  VERBATIM)
add_custom_target(cellphys_codegen DEPENDS ${CELLPHYS_GEN_STAMP})

# The generated headers include the SIMD layer (runtime/base) and nothing else of the runtime.
add_library(cellphys_generated INTERFACE)
add_dependencies(cellphys_generated cellphys_codegen)
target_include_directories(cellphys_generated INTERFACE ${CELLPHYS_GEN_DIR})
target_link_libraries(cellphys_generated INTERFACE cellphys_base)
