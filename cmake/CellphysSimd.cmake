# Choose the SIMD path at build time: auto (what this machine runs), avx512, avx2 or scalar.
# The scalar path is portable and must pass every test; CI builds and tests it too.
set(CELLPHYS_SIMD "auto" CACHE STRING "SIMD path: auto, avx512, avx2 or scalar")
set_property(CACHE CELLPHYS_SIMD PROPERTY STRINGS auto avx512 avx2 scalar)

set(_path "${CELLPHYS_SIMD}")
if(_path STREQUAL "auto")
  try_run(_run_rc _compile_ok
    SOURCES "${CMAKE_CURRENT_LIST_DIR}/detect_simd.cpp"
    RUN_OUTPUT_VARIABLE _detected)
  if(_compile_ok AND _run_rc EQUAL 0)
    string(STRIP "${_detected}" _path)
  else()
    set(_path scalar)
  endif()
endif()

set(CELLPHYS_SIMD_FLAGS)
set(CELLPHYS_SIMD_DEFINES)
if(_path STREQUAL "avx512")
  set(CELLPHYS_SIMD_FLAGS -mavx512f -mavx512vl -mavx512dq -mavx2 -mfma)
elseif(_path STREQUAL "avx2")
  set(CELLPHYS_SIMD_FLAGS -mavx2 -mfma)
elseif(_path STREQUAL "scalar")
  set(CELLPHYS_SIMD_DEFINES CELLPHYS_SIMD_SCALAR)
else()
  message(FATAL_ERROR "cellphys: CELLPHYS_SIMD must be auto, avx512, avx2 or scalar, not '${CELLPHYS_SIMD}'")
endif()
set(CELLPHYS_SIMD_PATH "${_path}")
message(STATUS "cellphys: SIMD path: ${CELLPHYS_SIMD_PATH}")
