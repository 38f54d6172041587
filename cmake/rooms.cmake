# aliquot_room(NAME [LINKS ...] [PUBLIC_LINKS ...]): one folder, one library. Its sources are
# the folder's *.cpp but the tests; its headers are visible only to targets that link it, so
# `target_link_libraries` is the list of rooms it may use and a wrong include fails to build.
# LINKS are private: a room sees what it links, not what those link in turn, so it names
# every room it includes. PUBLIC_LINKS are the exceptions, rooms whose types the room's own
# headers show, so whoever includes those headers needs them too (docs/ARCHITECTURE.md lists
# each one and why; `ctest -R room_links` checks the table against these lists).
# Its *_test.cpp files form one test binary, NAME_tests: they may use what the room links and
# TEST_LINKS.
function(aliquot_room name)
    cmake_parse_arguments(ROOM "" "" "LINKS;PUBLIC_LINKS;SOURCES;TEST_LINKS" ${ARGN})
    file(GLOB sources CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*.cpp)
    list(FILTER sources EXCLUDE REGEX "_test\\.cpp$")
    add_library(${name} ${sources} ${ROOM_SOURCES})
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
