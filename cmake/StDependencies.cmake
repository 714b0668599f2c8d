# Locates the Debian 12 packages the core needs. scripts/install-deps.sh installs them.
find_package(PkgConfig REQUIRED)
pkg_check_modules(CFITSIO REQUIRED IMPORTED_TARGET cfitsio)
pkg_check_modules(WCSLIB REQUIRED IMPORTED_TARGET wcslib)
pkg_check_modules(FFTW3F REQUIRED IMPORTED_TARGET fftw3f)
find_package(Eigen3 3.4 REQUIRED CONFIG)
find_package(nlohmann_json 3.10 REQUIRED CONFIG)
find_package(Threads REQUIRED)

# FFTW's threads library is not listed in its .pc file.
find_library(FFTW3F_THREADS_LIBRARY NAMES fftw3f_threads REQUIRED)

# libopencv-core-dev / libopencv-imgproc-dev ship no CMake or pkg-config files: find them by path.
find_path(OPENCV_INCLUDE_DIR opencv2/core.hpp PATH_SUFFIXES opencv4 REQUIRED)
find_library(OPENCV_CORE_LIBRARY NAMES opencv_core REQUIRED)
find_library(OPENCV_IMGPROC_LIBRARY NAMES opencv_imgproc REQUIRED)
add_library(st_opencv INTERFACE)
target_include_directories(st_opencv SYSTEM INTERFACE ${OPENCV_INCLUDE_DIR})
target_link_libraries(st_opencv INTERFACE ${OPENCV_IMGPROC_LIBRARY} ${OPENCV_CORE_LIBRARY})

# SEP (SExtractor as a C library, Debian libsep-dev): per-frame background meshes of real frames.
find_path(SEP_INCLUDE_DIR sep.h REQUIRED)
find_library(SEP_LIBRARY NAMES sep REQUIRED)
add_library(st_sep INTERFACE)
target_include_directories(st_sep SYSTEM INTERFACE ${SEP_INCLUDE_DIR})
target_link_libraries(st_sep INTERFACE ${SEP_LIBRARY})
