# Helpers shared by every CMakeLists.txt of the project.

# odonav_add_subdirectories(<glob>...)
# Adds each folder the globs match that has a CMakeLists.txt, in sorted order, so that a component
# or a test folder joins the build by itself.
function(odonav_add_subdirectories)
  file(GLOB _dirs LIST_DIRECTORIES true ${ARGN})
  list(SORT _dirs)
  foreach(_dir ${_dirs})
    if(EXISTS ${_dir}/CMakeLists.txt)
      add_subdirectory(${_dir})
    endif()
  endforeach()
endfunction()

# odonav_add_node_program(<program> NODE <library> SOURCES <files...> LINKS <targets...>)
# The common shape of a DDS program's folder (components/<name>/): the node library <library> from
# SOURCES, with the folder on its include path and LINKS as its public dependencies, and the
# program bin/<program> from the folder's main.cpp, linked to it.
function(odonav_add_node_program program)
  cmake_parse_arguments(ARG "" "NODE" "SOURCES;LINKS" ${ARGN})
  add_library(${ARG_NODE} STATIC ${ARG_SOURCES})
  target_include_directories(${ARG_NODE} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR})
  target_link_libraries(${ARG_NODE} PUBLIC ${ARG_LINKS})
  add_executable(${program} main.cpp)
  target_link_libraries(${program} PRIVATE ${ARG_NODE})
endfunction()

# odonav_add_gtest(<name> SOURCES <files...> LIBS <targets...> [LABELS <labels...>] [LANE <lane>]
#                  [ENVIRONMENT <VAR=...>...] [TIMEOUT <s>])
# Builds bin/odonav-test-<name> and registers each of its GoogleTest cases with CTest.
# Every test runs with SKIP_DEFAULT_XML=1 so a stray DEFAULT_FASTRTPS_PROFILES.xml cannot change it,
# and with the loopback-only profile as the default Fast DDS profile.
#
# Multi-process tests (label "integration") start several DDS programs each. By default one runs
# alone (RUN_SERIAL). With LANE <lane>, the tests of the lane run one at a time (RESOURCE_LOCK) but
# beside the tests of the other lane and the unit tests: most multi-process tests wait on real-time
# pacing, leases and restarts, so two lanes fill two cores. A lane's DDS domain ids must not be used
# by any test of the other lane (each CMakeLists.txt names its domains). The target
# odonav-integration-tests builds every multi-process test with the programs it starts (tests/CMakeLists.txt).
function(odonav_add_gtest name)
  cmake_parse_arguments(ARG "" "TIMEOUT;LANE" "SOURCES;LIBS;LABELS;ENVIRONMENT" ${ARGN})
  set(target odonav-test-${name})
  add_executable(${target} ${ARG_SOURCES})
  target_link_libraries(${target} PRIVATE ${ARG_LIBS} GTest::gtest GTest::gmock GTest::gtest_main)
  # tests/support: what the multi-process tests share (child processes, scratch folders).
  target_include_directories(${target} PRIVATE ${PROJECT_SOURCE_DIR}/tests/support)
  target_compile_definitions(${target} PRIVATE
    ODONAV_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
    ODONAV_BINARY_DIR="${PROJECT_BINARY_DIR}")
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 300)
  endif()
  # PROPERTIES takes key/value pairs: a list value must keep its ';' escaped or only its first
  # element survives, and an empty value would shift every pair after it (tests without labels are
  # labelled "unit").
  set(_labels "${ARG_LABELS}")
  if(NOT _labels)
    set(_labels unit)
  endif()
  string(REPLACE ";" "\\;" _labels "${_labels}")
  if("integration" IN_LIST ARG_LABELS)
    add_dependencies(odonav-integration-tests ${target})
    if(ARG_LANE)
      set(_schedule RESOURCE_LOCK "odonav-integration-lane-${ARG_LANE}")
    else()
      set(_schedule RUN_SERIAL TRUE)
    endif()
  elseif(ARG_LANE)
    message(FATAL_ERROR "odonav_add_gtest(${name}): LANE is for tests labelled integration")
  else()
    set(_schedule RUN_SERIAL FALSE)
  endif()
  gtest_discover_tests(${target}
    DISCOVERY_MODE PRE_TEST
    PROPERTIES
      TIMEOUT ${ARG_TIMEOUT}
      LABELS "${_labels}"
      ${_schedule}
      ENVIRONMENT "SKIP_DEFAULT_XML=1;FASTRTPS_DEFAULT_PROFILES_FILE=${PROJECT_SOURCE_DIR}/deploy/profiles/loopback.xml;${ARG_ENVIRONMENT}")
endfunction()
