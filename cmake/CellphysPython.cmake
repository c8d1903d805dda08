# Find a Python 3 that can import what the generator needs (jinja2, sympy, yaml).
# The first python3 on PATH may be another interpreter without Debian's packages, so every
# candidate is tried and the build stops with the missing module and its package named.
set(_cellphys_modules jinja2 sympy yaml)
set(_cellphys_packages python3-jinja2 python3-sympy python3-yaml)

set(_candidates)
if(CELLPHYS_PYTHON)
  list(APPEND _candidates "${CELLPHYS_PYTHON}")
endif()
list(APPEND _candidates /usr/bin/python3)
find_program(_path_python3 NAMES python3 python)
if(_path_python3)
  list(APPEND _candidates "${_path_python3}")
endif()
list(REMOVE_DUPLICATES _candidates)

set(CELLPHYS_GENERATOR_PYTHON "")
set(_report "")
foreach(py IN LISTS _candidates)
  if(NOT EXISTS "${py}")
    continue()
  endif()
  set(_missing "")
  foreach(mod pkg IN ZIP_LISTS _cellphys_modules _cellphys_packages)
    execute_process(COMMAND "${py}" -c "import ${mod}" RESULT_VARIABLE rc OUTPUT_QUIET ERROR_QUIET)
    if(NOT rc EQUAL 0)
      string(APPEND _missing " ${mod} (Debian package ${pkg})")
    endif()
  endforeach()
  if(_missing STREQUAL "")
    set(CELLPHYS_GENERATOR_PYTHON "${py}")
    break()
  endif()
  string(APPEND _report "\n  ${py}: cannot import${_missing}")
endforeach()

if(NOT CELLPHYS_GENERATOR_PYTHON)
  message(FATAL_ERROR
    "cellphys: no Python interpreter can run the code generator.${_report}\n"
    "Install the packages named above (scripts/setup does it: apt-get install python3-jinja2 "
    "python3-sympy python3-yaml), or point -DCELLPHYS_PYTHON=/path/to/python3 at one that has them.")
endif()
message(STATUS "cellphys: generator Python: ${CELLPHYS_GENERATOR_PYTHON}")
