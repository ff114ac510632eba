# One helper per target kind: idi_library, idi_test, idi_executable, idi_benchmark.
# Every target gets the project's warning set; -Werror when IDI_WERROR is ON.
include_guard(GLOBAL)

function(idi_set_warnings target)
  get_target_property(type ${target} TYPE)
  if(type STREQUAL "INTERFACE_LIBRARY")
    return()
  endif()
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow -Wconversion
                                           -Wno-sign-conversion $<$<BOOL:${IDI_WERROR}>:-Werror>)
endfunction()

# idi_library(<module> [SOURCES ...] [DEPS ...] [PRIVATE_DEPS ...])
# Makes idi_<module> with alias idi::<module>; the repository root is the include root.
function(idi_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS;PRIVATE_DEPS" ${ARGN})
  if(ARG_SOURCES)
    add_library(idi_${name} ${ARG_SOURCES})
    target_include_directories(idi_${name} PUBLIC ${PROJECT_SOURCE_DIR})
    target_link_libraries(idi_${name} PUBLIC ${ARG_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
    idi_set_warnings(idi_${name})
  else()
    add_library(idi_${name} INTERFACE)
    target_include_directories(idi_${name} INTERFACE ${PROJECT_SOURCE_DIR})
    target_link_libraries(idi_${name} INTERFACE ${ARG_DEPS})
  endif()
  add_library(idi::${name} ALIAS idi_${name})
endfunction()

# idi_test(<name> SOURCES ... [DEPS ...] [LABELS ...]): a GoogleTest executable registered with ctest.
function(idi_test name)
  if(NOT IDI_BUILD_TESTS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS;LABELS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gmock GTest::gtest_main)
  idi_set_warnings(${name})
  set(labels unit)
  if(ARG_LABELS)
    set(labels ${ARG_LABELS})
  endif()
  gtest_discover_tests(${name} DISCOVERY_MODE PRE_TEST DISCOVERY_TIMEOUT 60
                       WORKING_DIRECTORY ${PROJECT_SOURCE_DIR}
                       PROPERTIES LABELS "${labels}"
                                  ENVIRONMENT "IDI_SOURCE_DIR=${PROJECT_SOURCE_DIR}")
endfunction()

# idi_executable(<name> SOURCES ... [DEPS ...]): a deployable or tool executable.
function(idi_executable name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS})
  idi_set_warnings(${name})
endfunction()

# idi_benchmark(<name> SOURCES ... [DEPS ...]): a Google Benchmark program under tests/bench.
# Benchmarks are built with the tests but never run by ctest (they time things; tests never do).
function(idi_benchmark name)
  if(NOT IDI_BUILD_BENCHMARKS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} benchmark::benchmark)
  idi_set_warnings(${name})
endfunction()
