# Helpers shared by every CMakeLists.txt of the project.

# odonav_add_gtest(<name> SOURCES <files...> LIBS <targets...> [LABELS <labels...>] [ENVIRONMENT <VAR=...>...])
# Builds bin/odonav-test-<name> and registers each of its GoogleTest cases with CTest.
# Every test runs with SKIP_DEFAULT_XML=1 so a stray DEFAULT_FASTRTPS_PROFILES.xml cannot change it,
# and with the loopback-only profile as the default Fast DDS profile.
function(odonav_add_gtest name)
  cmake_parse_arguments(ARG "" "TIMEOUT" "SOURCES;LIBS;LABELS;ENVIRONMENT" ${ARGN})
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
  # element survives.
  string(REPLACE ";" "\\;" _labels "${ARG_LABELS}")
  # Multi-process tests (label "integration") run one at a time: each starts several DDS processes
  # that pace themselves on event time with bounded waits, and two such runs on a 2-core machine
  # starve each other. Unit tests still run in parallel.
  set(_serial FALSE)
  if("integration" IN_LIST ARG_LABELS)
    set(_serial TRUE)
  endif()
  gtest_discover_tests(${target}
    DISCOVERY_MODE PRE_TEST
    PROPERTIES
      TIMEOUT ${ARG_TIMEOUT}
      LABELS "${_labels}"
      RUN_SERIAL ${_serial}
      ENVIRONMENT "SKIP_DEFAULT_XML=1;FASTRTPS_DEFAULT_PROFILES_FILE=${PROJECT_SOURCE_DIR}/deploy/profiles/loopback.xml;${ARG_ENVIRONMENT}")
endfunction()
