# The rtl backend (src/rtl/): the Verilated chip of rtl/*.sv runs each collide. Included by the
# top-level CMakeLists.txt before the library targets. Sets BPX_RTL_BACKEND (default ON when
# BPX_RTL is on and Verilator's CMake package is found); without it src/rtl/stub.c says the
# backend is unavailable. bpx_rtl_objects(list) appends the Verilated chip's objects (C++, the
# Verilator runtime included) to the library's objects; bpx_rtl_link(target) links the C++
# runtime they need.
set(BPX_RTL_BACKEND_FOUND OFF)
# Turned off by name (the Python package), nothing is looked for: the library stays C alone.
if(BPX_RTL AND NOT (DEFINED BPX_RTL_BACKEND AND NOT BPX_RTL_BACKEND))
    # Verilator's package checks C++ flags: C++ first, where there is a compiler.
    include(CheckLanguage)
    check_language(CXX)
    if(CMAKE_CXX_COMPILER)
        enable_language(CXX)
        find_package(verilator QUIET HINTS $ENV{VERILATOR_ROOT} ${BPX_VERILATOR_ROOT})
    endif()
    if(verilator_FOUND)
        set(BPX_RTL_BACKEND_FOUND ON)
    endif()
endif()
option(BPX_RTL_BACKEND "Build the rtl backend: the Verilated chip in libbpx (needs Verilator 5)"
       ${BPX_RTL_BACKEND_FOUND})
if(BPX_RTL_BACKEND AND NOT BPX_RTL_BACKEND_FOUND)
    message(FATAL_ERROR "BPX_RTL_BACKEND is ON but BPX_RTL is OFF or Verilator's CMake package "
                        "was not found (Debian: apt-get install verilator)")
endif()
add_feature_info(rtl_backend BPX_RTL_BACKEND "the rtl backend: the Verilated chip (rtl/)")

if(BPX_RTL_BACKEND)
    list(APPEND BPX_SOURCES src/rtl/backend.c)
    # For the installed package: consumers of the static library link the C++ runtime too.
    string(APPEND BPX_PC_LIBS_PRIVATE " -lstdc++")
else()
    list(APPEND BPX_SOURCES src/rtl/stub.c)
endif()

# After bpx_objects: the board driver (src/rtl/board.cpp) and the Verilated board, appended to
# the list named by `objects` (nothing without the backend). The chip's parameters are the
# paper's build (src/rtl/board.h).
function(bpx_rtl_objects objects)
    if(NOT BPX_RTL_BACKEND)
        return()
    endif()
    add_library(bpx_rtl_board OBJECT src/rtl/board.cpp)
    target_compile_features(bpx_rtl_board PRIVATE cxx_std_14)
    target_include_directories(bpx_rtl_board PRIVATE ${PROJECT_SOURCE_DIR}/include
                               ${PROJECT_SOURCE_DIR}/src)
    target_compile_definitions(bpx_rtl_board PRIVATE BPX_BUILDING)
    # Nothing of the Verilator runtime is exported from libbpx.so.
    set_target_properties(bpx_rtl_board PROPERTIES CXX_VISIBILITY_PRESET hidden
                          VISIBILITY_INLINES_HIDDEN ON)
    set(rtl ${PROJECT_SOURCE_DIR}/rtl)
    verilate(bpx_rtl_board PREFIX Vbpx_rtl_board TOP_MODULE bpx_board
        SOURCES ${rtl}/bpx_board.sv ${rtl}/bpx_chip.sv ${rtl}/interface.sv ${rtl}/updater.sv
                ${rtl}/comparator.sv ${rtl}/emitter.sv ${rtl}/fadd.sv
        VERILATOR_ARGS -Wno-fatal -Wno-WIDTH -O3 -GM=4 -GDEPTH=512 -GFDEPTH=1024 -GLAT=2)
    # Verilated C++ is not held to the project's warning flags; board.cpp is.
    get_target_property(sources bpx_rtl_board SOURCES)
    foreach(source ${sources})
        if(source MATCHES "\\.cpp$" AND NOT source STREQUAL "src/rtl/board.cpp")
            set_property(SOURCE ${source} TARGET_DIRECTORY bpx_rtl_board APPEND PROPERTY
                         COMPILE_OPTIONS -w)
        endif()
    endforeach()
    set(${objects} ${${objects}} $<TARGET_OBJECTS:bpx_rtl_board> PARENT_SCOPE)
endfunction()

function(bpx_rtl_link target)
    if(BPX_RTL_BACKEND)
        target_link_libraries(${target} PRIVATE stdc++)
    endif()
endfunction()
