# cellphys_generate(<target> OUT <dir> FORCE_DIRS <dir>...)
#
# Generates the kernels and layouts of one force set -- the force descriptors in FORCE_DIRS, with
# the struct descriptors of codegen/descriptors/structs -- into OUT, again whenever a descriptor,
# template or generator file changes, and makes <target> an INTERFACE library: what links it
# compiles against that set (cellphys/gen/... from OUT) and runtime/base.
# The main build's set is cellphys_generated; the checked-in generated/ is compared with a fresh
# generation of it by the codegen_drift test.
function(cellphys_generate target)
  cmake_parse_arguments(PARSE_ARGV 1 arg "" "OUT" "FORCE_DIRS")
  get_filename_component(root ${CMAKE_CURRENT_FUNCTION_LIST_DIR} DIRECTORY)
  file(GLOB inputs CONFIGURE_DEPENDS
    ${root}/codegen/*.py
    ${root}/codegen/cellphys_codegen/*.py
    ${root}/codegen/descriptors/structs/*.yaml
    ${root}/templates/*.j2
    ${root}/templates/util/*.jinja)
  set(stamp ${arg_OUT}/cellphys/gen/.stamp)
  # The headers are byproducts, so the build knows the sources that include them must wait for
  # a regeneration and be re-checked after it (a force header is named after its descriptor's name).
  set(headers)
  foreach(name layouts.h layouts.json kernel_types.h force_table.h block_ops.h)
    list(APPEND headers ${arg_OUT}/cellphys/gen/${name})
  endforeach()
  set(force_args)
  foreach(dir ${arg_FORCE_DIRS})
    get_filename_component(dir ${dir} ABSOLUTE BASE_DIR ${root})
    file(GLOB yamls CONFIGURE_DEPENDS ${dir}/*.yaml)
    foreach(yaml ${yamls})
      file(STRINGS ${yaml} name_line REGEX "^name:" LIMIT_COUNT 1)
      if(name_line MATCHES "^name:[ \t]*[\"']?([a-z0-9_]+)")
        list(APPEND headers ${arg_OUT}/cellphys/gen/forces/${CMAKE_MATCH_1}.h)
      endif()
    endforeach()
    list(APPEND inputs ${yamls})
    list(APPEND force_args --forces ${dir})
  endforeach()
  add_custom_command(
    OUTPUT ${stamp}
    BYPRODUCTS ${headers}
    COMMAND ${CELLPHYS_GENERATOR_PYTHON} ${root}/codegen/generate.py --out ${arg_OUT} ${force_args}
    DEPENDS ${inputs}
    COMMENT "cellphys: generating kernels and layouts of ${target}"
    VERBATIM)
  add_custom_target(${target}_codegen DEPENDS ${stamp})

  add_library(${target} INTERFACE)
  add_dependencies(${target} ${target}_codegen)
  # The generated headers include the SIMD layer (runtime/base) and nothing else of the runtime.
  target_include_directories(${target} INTERFACE ${arg_OUT})
  target_link_libraries(${target} INTERFACE cellphys_base)
endfunction()
