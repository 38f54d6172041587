# aliquot_room(NAME [LINKS ...] [PUBLIC_LINKS ...]): one folder, one library. Its sources are
# the folder's *.cpp but the tests; its headers are visible only to targets that link it, so
# `target_link_libraries` is the list of rooms it may use and a wrong include fails to build.
# LINKS are private: a room sees what it links, not what those link in turn, so it names
# every room it includes. PUBLIC_LINKS are the exceptions, rooms whose types the room's own
# headers show, so whoever includes those headers needs them too (docs/ARCHITECTURE.md lists
# each one and why; `ctest -R room_links` checks the table against these lists).
# Its *_test.cpp files form one test binary, NAME_tests: they may use what the room links and
# TEST_LINKS.
# ALIQUOT_UNITY_ROOMS compiles each room's library (not its tests) as a unity build:
# batches of its files in one translation unit each, so nlohmann/json's, gRPC's and the
# room's own inline code compile once a batch instead of once a file. It is for one-off
# builds (scripts/demo.sh turns it on); off, editing a file recompiles that file alone.
# Names in a room's anonymous namespaces must therefore differ across its files. The
# tracer compiles file by file either way: its inner loops' code is what was measured.
option(ALIQUOT_UNITY_ROOMS "Compile each room's library as a unity build (scripts/demo.sh)" OFF)
set(ALIQUOT_UNITY_SKIP aliquot_tracer)
# Files whose anonymous namespaces repeat a name of another file of their room (kRgb,
# kDefaultMaxSpp, kImageFactor, in_quotes, iequals): they compile alone in a unity build.
# Nothing but scripts/demo.sh builds this way, so a new repeat shows there first; demo.sh
# then builds file by file.
set(ALIQUOT_UNITY_ALONE coordinator/image/exr_rgb_copy.cpp
    coordinator/strategies/dammertz_strategy.cpp coordinator/strategies/denoised_strategy.cpp
    coordinator/study/study_plan.cpp coordinator/api/http_front.cpp)
function(aliquot_room name)
    cmake_parse_arguments(ROOM "" "" "LINKS;PUBLIC_LINKS;SOURCES;TEST_LINKS" ${ARGN})
    file(GLOB sources CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*.cpp)
    list(FILTER sources EXCLUDE REGEX "_test\\.cpp$")
    add_library(${name} ${sources} ${ROOM_SOURCES})
    if(ALIQUOT_UNITY_ROOMS AND NOT name IN_LIST ALIQUOT_UNITY_SKIP)
        # A batch parses nlohmann/json once anyway: making a room's precompiled header
        # (scripts/demo.sh's build) would cost more than the one or two batches it serves.
        set_target_properties(${name} PROPERTIES UNITY_BUILD ON DISABLE_PRECOMPILE_HEADERS ON)
        foreach(file IN LISTS ALIQUOT_UNITY_ALONE)
            set_source_files_properties(${PROJECT_SOURCE_DIR}/${file}
                PROPERTIES SKIP_UNITY_BUILD_INCLUSION ON)
        endforeach()
    endif()
    target_include_directories(${name} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR})
    target_link_libraries(${name} PUBLIC ${ROOM_PUBLIC_LINKS} PRIVATE ${ROOM_LINKS})

    file(GLOB tests CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*_test.cpp)
    if(tests)
        add_executable(${name}_tests ${tests})
        target_link_libraries(${name}_tests PRIVATE ${name} ${ROOM_LINKS} ${ROOM_TEST_LINKS}
            GTest::gtest_main)
        target_compile_definitions(${name}_tests PRIVATE ALIQUOT_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
        gtest_discover_tests(${name}_tests DISCOVERY_TIMEOUT 60)
    endif()
endfunction()
