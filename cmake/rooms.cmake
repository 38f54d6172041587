# aliquot_room(NAME [LINKS ...] [PRIVATE_LINKS ...]): one folder, one library. Its sources are
# the folder's *.cpp but the tests; its headers are visible only to targets that link it, so
# `target_link_libraries` is the list of rooms it may use and a wrong include fails to build.
# Its *_test.cpp files form one test binary, NAME_tests, linked with TEST_LINKS.
function(aliquot_room name)
    cmake_parse_arguments(ROOM "" "" "LINKS;PRIVATE_LINKS;SOURCES;TEST_LINKS" ${ARGN})
    file(GLOB sources CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*.cpp)
    list(FILTER sources EXCLUDE REGEX "_test\\.cpp$")
    add_library(${name} ${sources} ${ROOM_SOURCES})
    target_include_directories(${name} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR})
    target_link_libraries(${name} PUBLIC ${ROOM_LINKS} PRIVATE ${ROOM_PRIVATE_LINKS})

    file(GLOB tests CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*_test.cpp)
    if(tests)
        add_executable(${name}_tests ${tests})
        target_link_libraries(${name}_tests PRIVATE ${name} ${ROOM_TEST_LINKS} GTest::gtest_main)
        target_compile_definitions(${name}_tests PRIVATE ALIQUOT_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
        gtest_discover_tests(${name}_tests DISCOVERY_TIMEOUT 60)
    endif()
endfunction()
