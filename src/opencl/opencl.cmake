# The OpenCL backend (src/opencl/): included by the top-level CMakeLists.txt before the library
# targets. Sets BPX_OPENCL (ON when OpenCL headers and an ICD loader are found), appends the
# backend's sources to BPX_SOURCES and its define to BPX_SIMD_DEFINES; bpx_opencl_link(target)
# links OpenCL where the backend is built.
find_package(OpenCL QUIET)
option(BPX_OPENCL "Build the opencl backend (needs OpenCL headers and an ICD loader)"
       ${OpenCL_FOUND})
if(BPX_OPENCL AND NOT OpenCL_FOUND)
    message(FATAL_ERROR "BPX_OPENCL is ON but OpenCL was not found "
                        "(Debian: apt-get install ocl-icd-opencl-dev opencl-c-headers)")
endif()
add_feature_info(opencl BPX_OPENCL "the opencl backend (OpenCL ${OpenCL_VERSION_STRING})")

set(BPX_OPENCL_DIR ${CMAKE_CURRENT_LIST_DIR})
if(BPX_OPENCL)
    # The program is these files in this order, embedded at build time.
    set(BPX_OPENCL_KERNELS
        ${BPX_OPENCL_DIR}/kernels/twin.h
        ${BPX_OPENCL_DIR}/../kernels/lbvh_build.h
        ${BPX_OPENCL_DIR}/kernels/lbvh.h
        ${BPX_OPENCL_DIR}/../kernels/lbvh_walk.h
        ${BPX_OPENCL_DIR}/kernels/update.cl
        ${BPX_OPENCL_DIR}/kernels/brute.cl
        ${BPX_OPENCL_DIR}/kernels/scan.cl
        ${BPX_OPENCL_DIR}/kernels/sort.cl
        ${BPX_OPENCL_DIR}/kernels/sweep.cl
        ${BPX_OPENCL_DIR}/kernels/tree.cl)
    set(BPX_OPENCL_EMBEDDED ${PROJECT_BINARY_DIR}/generated/bpx_opencl_kernels.c)
    add_custom_command(
        OUTPUT ${BPX_OPENCL_EMBEDDED}
        COMMAND ${CMAKE_COMMAND} -DOUT=${BPX_OPENCL_EMBEDDED} "-DSOURCES=${BPX_OPENCL_KERNELS}"
                -P ${BPX_OPENCL_DIR}/embed.cmake
        DEPENDS ${BPX_OPENCL_KERNELS} ${BPX_OPENCL_DIR}/embed.cmake
        COMMENT "Embedding the OpenCL kernels"
        VERBATIM)
    list(APPEND BPX_SOURCES
        src/opencl/brute.c
        src/opencl/buffers.c
        src/opencl/device.c
        src/opencl/opencl.c
        src/opencl/resident.c
        src/opencl/sort.c
        src/opencl/sweep.c
        src/opencl/tree.c
        src/opencl/twin.c
        src/opencl/update.c
        ${BPX_OPENCL_EMBEDDED})
    list(APPEND BPX_SIMD_DEFINES BPX_HAVE_OPENCL=1)
    # For the installed package: consumers of the static library link OpenCL too.
    set(BPX_PC_LIBS_PRIVATE "-lOpenCL")
else()
    list(APPEND BPX_SOURCES src/opencl/stub.c)
    set(BPX_PC_LIBS_PRIVATE "")
endif()

function(bpx_opencl_link target)
    if(BPX_OPENCL)
        target_link_libraries(${target} PRIVATE OpenCL::OpenCL)
    endif()
endfunction()
