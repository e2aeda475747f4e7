# calib_add_library(NAME SOURCES ... DEPENDS ...): one library per top-level
# folder, aliased as calib::NAME, public headers under include/calib/NAME.
function(calib_add_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPENDS;PRIVATE_DEPENDS" ${ARGN})
  add_library(calib_${name} ${ARG_SOURCES})
  add_library(calib::${name} ALIAS calib_${name})
  target_include_directories(calib_${name} PUBLIC
    $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include>)
  target_link_libraries(calib_${name} PUBLIC ${ARG_PUBLIC_DEPENDS} PRIVATE ${ARG_PRIVATE_DEPENDS})
  target_compile_options(calib_${name} PRIVATE -Wall -Wextra -Wpedantic)
endfunction()

# The test programs' own code is compiled with -Og in an optimised build:
# what they exercise is the libraries, compiled as a user's (-O3), and a
# test file's compile time is mostly gtest's, nlohmann-json's and Eigen's
# templates, which -Og emits in half the time (a loop test's file: 20 s at
# -O3, 10 s at -Og). Results do not change: no fast-math either way, and
# the default x86-64 target the test files are built for has no fused
# multiply-add to contract into (the libraries' AVX-512 kernels, which
# may, are built with the libraries).
set(CALIB_TEST_OPTIMIZATION $<$<NOT:$<CONFIG:Debug>>:-Og>)

# calib_add_test(NAME SOURCES ... DEPENDS ... [TIMEOUT SECONDS] [COST SECONDS]):
# one GoogleTest executable, registered with ctest. Tests find ../shared
# through CALIB_SHARED_DIR. TIMEOUT overrides ctest's --timeout for each of
# its tests (whole calibrations). COST is about how long its longest test
# runs: ctest -j starts the costliest tests first where it has no timings of
# its own yet (a fresh clone, as in CI), so that a long test does not start
# last and run alone on an otherwise idle machine.
function(calib_add_test name)
  cmake_parse_arguments(ARG "" "TIMEOUT;COST" "SOURCES;DEPENDS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPENDS} calib_test_support GTest::gtest_main)
  target_compile_options(${name} PRIVATE -Wall -Wextra ${CALIB_TEST_OPTIMIZATION})
  # OMP_WAIT_POLICY=passive: ctest -j runs several tests at once, each with
  # OpenMP threads, and libgomp's threads spinning at a barrier take the
  # cores the other tests need (two loop tests side by side on 2 cores:
  # 101-106 s active, 84-92 s passive). LABELS gtest: scripts/sanitize.sh
  # runs these programs itself and the other tests (ctest -LE gtest)
  # through ctest.
  # (One variable per property: a list would be split into property names.)
  set(properties ENVIRONMENT "CALIB_SHARED_DIR=${CALIB_SHARED_DIR}"
                 ENVIRONMENT_MODIFICATION "OMP_WAIT_POLICY=set:passive" LABELS gtest)
  if(ARG_TIMEOUT)
    list(APPEND properties TIMEOUT ${ARG_TIMEOUT})
  endif()
  if(ARG_COST)
    list(APPEND properties COST ${ARG_COST})
  endif()
  gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60 PROPERTIES ${properties})
endfunction()
