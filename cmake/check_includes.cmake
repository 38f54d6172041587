# Fails when a source includes a project header by a path (`#include "../store/store.h"`):
# rooms see each other only through their include directories, which their CMake links grant,
# and a path would walk around that wall. Run by ctest as include_walls.
file(GLOB_RECURSE sources ${ROOT}/coordinator/*.cpp ${ROOT}/coordinator/*.h ${ROOT}/worker/*.cpp
     ${ROOT}/worker/*.h ${ROOT}/cli/*.cpp ${ROOT}/cli/*.h ${ROOT}/proto/*.cpp ${ROOT}/proto/*.h ${ROOT}/input/*.cpp ${ROOT}/input/*.h
     ${ROOT}/bench/*.cpp ${ROOT}/fuzz/*.cpp)
set(bad "")
foreach(f ${sources})
    file(STRINGS ${f} lines REGEX "^#include \"[^\"]*/")
    foreach(line ${lines})
        file(RELATIVE_PATH rel ${ROOT} ${f})
        string(APPEND bad "\n  ${rel}: ${line}")
    endforeach()
endforeach()
if(bad)
    message(FATAL_ERROR "project headers are included by name, not by path:${bad}")
endif()
