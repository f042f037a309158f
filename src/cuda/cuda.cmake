# The cuda backend (src/cuda/): included by the top-level CMakeLists.txt before the library
# targets. Sets BPX_CUDA (ON when CMake finds a CUDA compiler), appends the backend's sources to
# BPX_SOURCES and its define to BPX_SIMD_DEFINES; bpx_cuda_link(target) links the CUDA runtime
# (static, so users of libbpx need no CUDA at build time) where the backend is built.
include(CheckLanguage)
check_language(CUDA)
set(BPX_CUDA_FOUND OFF)
if(CMAKE_CUDA_COMPILER)
    set(BPX_CUDA_FOUND ON)
endif()
option(BPX_CUDA "Build the cuda backend (needs the CUDA toolkit: nvcc, CUB)" ${BPX_CUDA_FOUND})
if(BPX_CUDA AND NOT CMAKE_CUDA_COMPILER)
    message(FATAL_ERROR "BPX_CUDA is ON but no CUDA compiler was found (set CMAKE_CUDA_COMPILER)")
endif()

if(BPX_CUDA)
    # Hopper machine code, plus PTX that any GPU since Turing compiles at load time. Set
    # CMAKE_CUDA_ARCHITECTURES for others (e.g. "native" where the GPU is present).
    if(NOT DEFINED CMAKE_CUDA_ARCHITECTURES)
        set(CMAKE_CUDA_ARCHITECTURES 90-real 75-virtual)
    endif()
    enable_language(CUDA)
    # Exactness: fast math flushes subnormal coordinates to zero in the comparisons that decide
    # the pairs; refused. No contraction into FMA (as -ffp-contract=off for C): the centres
    # behind the Morton codes round as on the host, so the host twin builds the device's tree
    # (and nvcc's host compiler contracts nothing either: the twins are host code).
    string(TOUPPER "${CMAKE_BUILD_TYPE}" bpx_cuda_config)
    if("${CMAKE_CUDA_FLAGS} ${CMAKE_CUDA_FLAGS_${bpx_cuda_config}}" MATCHES
       "use_fast_math|ftz=true")
        message(FATAL_ERROR "the cuda backend is exact only without fast math / -ftz=true")
    endif()
    add_compile_options("$<$<COMPILE_LANGUAGE:CUDA>:--fmad=false>"
                        "$<$<COMPILE_LANGUAGE:CUDA>:-Xcompiler=-ffp-contract=off>")
    set(CMAKE_CUDA_STANDARD 17)
    set(CMAKE_CUDA_STANDARD_REQUIRED ON)
    find_package(CUDAToolkit REQUIRED)
    # The kernels and sorts are an object library of their own (bpx_cuda_kernels, made by
    # bpx_cuda_kernel_objects): the fake device's tests (test/fake_cuda/) link the same host
    # objects with host loops in their place.
    list(APPEND BPX_SOURCES src/cuda/backend.c src/cuda/buffers.cu src/cuda/cycle.cu)
    list(APPEND BPX_SIMD_DEFINES BPX_HAVE_CUDA=1)
    add_feature_info(cuda BPX_CUDA "the cuda backend (CUDA ${CUDAToolkit_VERSION})")
    # For the installed package: consumers of the static library link the CUDA runtime too.
    # CUB's host code needs the C++ runtime (static locals' guards).
    string(APPEND BPX_PC_LIBS_PRIVATE
           " -L${CUDAToolkit_LIBRARY_DIR} -lcudart_static -ldl -lrt -lstdc++")
else()
    # The calls of include/bpx/cuda.h are core/device.c's: on a world of another backend they
    # say BACKEND_UNAVAILABLE.
    add_feature_info(cuda BPX_CUDA "the cuda backend")
endif()

# After bpx_objects: the kernels' objects, built like the library's own, appended to the list
# named by `objects` (nothing without CUDA).
function(bpx_cuda_kernel_objects objects)
    if(BPX_CUDA)
        add_library(bpx_cuda_kernels OBJECT src/cuda/kernels.cu)
        foreach(property INCLUDE_DIRECTORIES COMPILE_DEFINITIONS)
            set_property(TARGET bpx_cuda_kernels PROPERTY ${property}
                         $<TARGET_PROPERTY:bpx_objects,${property}>)
        endforeach()
        set(${objects} ${${objects}} $<TARGET_OBJECTS:bpx_cuda_kernels> PARENT_SCOPE)
    endif()
endfunction()

function(bpx_cuda_link target)
    if(BPX_CUDA)
        target_link_libraries(${target} PRIVATE CUDA::cudart_static stdc++)
    endif()
endfunction()
