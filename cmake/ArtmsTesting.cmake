# Test helpers. Every ctest test carries exactly one of the labels of
# DESIGN.md section 10: unit, oracle, integration, soak, bench.

include(GoogleTest)

# artms_add_gtest(NAME <name> LABEL <label> SOURCES ... LIBS ...
#                 [FIXTURES <fixture>] [ENVIRONMENT VAR=value ...])
# One GoogleTest executable; each TEST() becomes a ctest test with the label.
function(artms_add_gtest)
  cmake_parse_arguments(ARG "" "NAME;LABEL;FIXTURES" "SOURCES;LIBS;ENVIRONMENT" ${ARGN})
  set(extra_props "")
  if(ARG_FIXTURES)
    list(APPEND extra_props FIXTURES_REQUIRED ${ARG_FIXTURES})
  endif()
  if(ARG_ENVIRONMENT)
    list(APPEND extra_props ENVIRONMENT "${ARG_ENVIRONMENT}")
  endif()
  add_executable(${ARG_NAME} ${ARG_SOURCES})
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_LIBS} artms_test_support
    GTest::gtest GTest::gmock GTest::gtest_main)
  artms_set_warnings(${ARG_NAME})
  gtest_discover_tests(${ARG_NAME}
    PROPERTIES LABELS ${ARG_LABEL} ${extra_props}
    DISCOVERY_TIMEOUT 60)
endfunction()

# Locate Debian's python3 that can import the oracle packages. Oracle tests
# call it explicitly: a python3 earlier on PATH may not see Debian's modules.
set(ARTMS_ORACLE_PYTHON /usr/bin/python3 CACHE FILEPATH
  "Python interpreter with Debian's poliastro, scipy, sklearn, skyfield")
