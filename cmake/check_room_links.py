#!/usr/bin/env python3
"""Checks that docs/ARCHITECTURE.md's "may use" column is what the build enforces.

Run by ctest as room_links, beside include_walls. For every room in the table:
1. its "may use" column equals its CMake link list, `(public)` marking PUBLIC_LINKS;
2. its sources include headers only of rooms it links (a PUBLIC link of a room it links
   would let the compiler accept more), its tests also of its TEST_LINKS;
3. it includes something of every room it links: no link is there for nothing;
4. a room is linked PUBLIC exactly when a header of the room that others include shows it.
Names: `aliquot_X` is room X, other CMake targets are mapped by EXTERNAL.
"""
import os
import re
import sys

ROOT = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..")

EXTERNAL = {
    "nlohmann_json::nlohmann_json": "nlohmann_json",
    "OpenEXR::OpenEXR": "OpenEXR",
    "ZLIB::ZLIB": "zlib",
    "SQLite::SQLite3": "SQLite",
    "embree": "Embree",
    "Threads::Threads": "Threads",
    "PkgConfig::HTTPLIB": "httplib",
    "PkgConfig::GRPCPP": "gRPC",
    "protobuf::libprotobuf": "protobuf",
    "${GRPCPP_REFLECTION}": "grpc++_reflection",
    "prometheus-cpp::core": "prometheus-cpp",
    "OpenSSL::SSL": "OpenSSL",
    "CLI11::CLI11": "CLI11",
    "${CMAKE_DL_LIBS}": "libdl",
}
# Generated headers: they live in the build tree, their room is the target that makes them.
GENERATED = {"aliquot.pb.h": "proto", "aliquot.grpc.pb.h": "proto"}
# Folders outside the table whose includes count as "others include this header".
USERS_OUTSIDE = ["bench", "fuzz"]


def name_of(target):
    if target.startswith("aliquot_"):
        return target[len("aliquot_"):]
    if target not in EXTERNAL:
        sys.exit(f"room_links: no table name for CMake target {target} (add it to EXTERNAL)")
    return EXTERNAL[target]


def table_rows():
    rows = {}
    text = open(os.path.join(ROOT, "docs/ARCHITECTURE.md"), encoding="utf-8").read()
    for m in re.finditer(r"^\| `([^`]+)/` \|.*\| ([^|]*) \|$", text, re.M):
        uses = {}
        for token in m.group(2).split(","):
            token = token.strip()
            if token in ("", "nothing"):
                continue
            public = token.endswith(" (public)")
            uses[token.removesuffix(" (public)")] = public
        rows[m.group(1)] = uses
    return rows


def cmake_links(folder):
    """(target, {name: public}, {test link names}) of the folder's room or executable."""
    text = open(os.path.join(ROOT, folder, "CMakeLists.txt"), encoding="utf-8").read()
    text = re.sub(r"#[^\n]*", "", text)
    m = re.search(r"aliquot_room\(\s*(\S+)([^)]*)\)", text)
    if m:
        links, tests, keyword = {}, set(), None
        for word in m.group(2).split():
            if word in ("LINKS", "PUBLIC_LINKS", "TEST_LINKS", "SOURCES"):
                keyword = word
            elif keyword == "LINKS":
                links[name_of(word)] = False
            elif keyword == "PUBLIC_LINKS":
                links[name_of(word)] = True
            elif keyword == "TEST_LINKS":
                tests.add(name_of(word))
        return m.group(1), links, tests
    m = re.search(r"target_link_libraries\(\s*(\S+)\s+PRIVATE([^)]*)\)", text)
    return m.group(1), {name_of(w): False for w in m.group(2).split()}, set()


def sources(folder):
    path = os.path.join(ROOT, folder)
    return sorted(f for f in os.listdir(path) if f.endswith((".h", ".cpp")))


def includes(folder, name):
    with open(os.path.join(ROOT, folder, name), encoding="utf-8", errors="replace") as f:
        # Project headers by quotes; gRPC's generated health service by angle brackets.
        return re.findall(r'^\s*#\s*include\s+(?:"([^"]+)"|<(grpc/health/[^>]+)>)', f.read(), re.M)


def main():
    rows = table_rows()
    if not rows:
        sys.exit("room_links: found no table in docs/ARCHITECTURE.md")
    room_of_folder, links, test_links = {}, {}, {}
    for folder in rows:
        target, links[folder], test_links[folder] = cmake_links(folder)
        # A room is its target's name; an executable (cli/) is its folder's.
        room_of_folder[folder] = name_of(target) if target.startswith("aliquot_") else folder
    header_room = dict(GENERATED)
    for folder in list(rows) + USERS_OUTSIDE:
        for f in sources(folder):
            if f.endswith(".h"):
                header_room[f] = room_of_folder.get(folder, folder)

    def room_of(include):
        if include.startswith("grpc/health/"):
            return "grpc_health"
        return header_room.get(os.path.basename(include))

    errors = []
    # Which headers of each room others include (the rooms' tests, bench and fuzz count).
    included_outside = set()
    for folder in list(rows) + USERS_OUTSIDE:
        for f in sources(folder):
            for inc in includes(folder, f):
                inc = "".join(inc)
                room = room_of(inc)
                if room is not None and room != room_of_folder.get(folder, folder):
                    included_outside.add((room, os.path.basename(inc)))

    for folder, uses in rows.items():
        room = room_of_folder[folder]
        if uses != links[folder]:
            def spell(d):
                return ", ".join(f"{k}{' (public)' if v else ''}" for k, v in sorted(d.items()))
            errors.append(f"{folder}/: the table says may use [{spell(uses)}], "
                          f"its CMakeLists.txt links [{spell(links[folder])}]")
        used = set()
        # Rooms each header shows, through the room's own headers it includes.
        direct = {}
        for f in sources(folder):
            others, own = set(), set()
            for inc in includes(folder, f):
                inc = "".join(inc)
                other = room_of(inc)
                if other is None or other == room:
                    own.add(os.path.basename(inc))
                    continue
                test = f.endswith("_test.cpp")
                allowed = set(links[folder]) | (test_links[folder] if test else set())
                if other not in allowed:
                    errors.append(f"{folder}/{f} includes {inc} of room {other}, "
                                  f"which {folder}/CMakeLists.txt does not link")
                if not test:
                    used.add(other)
                others.add(other)
            direct[f] = (others, own)
        rooms_links = {k for k in links[folder] if k in room_of_folder.values() or
                       k in ("proto", "grpc_health")}
        for unused in sorted(rooms_links - used):
            errors.append(f"{folder}/ links {unused} but includes nothing of it")

        def shows(header, seen):
            if header in seen or header not in direct:
                return set()
            seen.add(header)
            others, own = direct[header]
            result = set(others)
            for h in own:
                result |= shows(h, seen)
            return result

        shown = set()
        for f in direct:
            if f.endswith(".h") and (room, f) in included_outside:
                shown |= shows(f, set())
        for name, public in sorted(links[folder].items()):
            if name not in rooms_links:
                continue
            if public and name not in shown:
                errors.append(f"{folder}/ links {name} PUBLIC, but no header others include "
                              f"shows it: make it a private link")
            if not public and name in shown:
                errors.append(f"{folder}/ links {name} privately, but a header others include "
                              f"shows it: make it PUBLIC_LINKS (and say why in ARCHITECTURE.md)")
    if errors:
        print("room_links: docs/ARCHITECTURE.md and the CMake link lists disagree:")
        for e in errors:
            print("  " + e)
        sys.exit(1)
    print(f"room_links: {len(rows)} rooms, table and links agree")


main()
