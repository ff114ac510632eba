# find_package(OpenCV COMPONENTS ...) for a sysroot holding Debian's per-module OpenCV packages
# (libopencv-core-dev, libopencv-imgproc-dev, ...) but not the libopencv-dev metapackage that carries
# the real OpenCVConfig.cmake. Makes the same imported targets (opencv_core, opencv_imgproc, ...)
# from the libraries found in the sysroot. Selected by toolchains/cmake/IdiCrossSysroot.cmake.
find_path(OpenCV_INCLUDE_DIR opencv2/core.hpp PATH_SUFFIXES opencv4)
set(OpenCV_FOUND FALSE)
if(NOT OpenCV_INCLUDE_DIR)
  set(OpenCV_NOT_FOUND_MESSAGE "opencv2/core.hpp not found in the sysroot (libopencv-core-dev)")
  return()
endif()
set(OpenCV_INCLUDE_DIRS ${OpenCV_INCLUDE_DIR})
file(STRINGS "${OpenCV_INCLUDE_DIR}/opencv2/core/version.hpp" _idi_cv_version
     REGEX "#define CV_VERSION_(MAJOR|MINOR|REVISION) ")
foreach(_idi_part MAJOR MINOR REVISION)
  string(REGEX REPLACE ".*#define CV_VERSION_${_idi_part} +([0-9]+).*" "\\1" OpenCV_VERSION_${_idi_part}
         "${_idi_cv_version}")
endforeach()
set(OpenCV_VERSION "${OpenCV_VERSION_MAJOR}.${OpenCV_VERSION_MINOR}.${OpenCV_VERSION_REVISION}")

# Module dependencies as OpenCV declares them (core at the bottom).
set(_idi_cv_deps_imgproc core)
set(_idi_cv_deps_imgcodecs core imgproc)
set(_idi_cv_deps_videoio core imgproc imgcodecs)
set(_idi_cv_deps_features2d core imgproc flann)
set(_idi_cv_deps_flann core)
set(_idi_cv_deps_calib3d core imgproc features2d flann)
set(_idi_cv_deps_highgui core imgproc imgcodecs videoio)
set(_idi_cv_wanted ${OpenCV_FIND_COMPONENTS})
if(NOT _idi_cv_wanted)
  set(_idi_cv_wanted core imgproc)
endif()
set(OpenCV_LIBS)
set(OpenCV_FOUND TRUE)
foreach(_idi_module core ${_idi_cv_wanted})
  if(TARGET opencv_${_idi_module})
    continue()
  endif()
  find_library(OpenCV_${_idi_module}_LIBRARY opencv_${_idi_module})
  if(NOT OpenCV_${_idi_module}_LIBRARY)
    if(OpenCV_FIND_REQUIRED_${_idi_module})
      set(OpenCV_FOUND FALSE)
      string(APPEND OpenCV_NOT_FOUND_MESSAGE "opencv_${_idi_module} not in the sysroot "
                                             "(libopencv-${_idi_module}-dev). ")
    endif()
    continue()
  endif()
  add_library(opencv_${_idi_module} SHARED IMPORTED)
  set(_idi_cv_links)
  foreach(_idi_dep ${_idi_cv_deps_${_idi_module}})
    list(APPEND _idi_cv_links opencv_${_idi_dep})
  endforeach()
  set_target_properties(opencv_${_idi_module} PROPERTIES
    IMPORTED_LOCATION "${OpenCV_${_idi_module}_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${OpenCV_INCLUDE_DIR}"
    INTERFACE_LINK_LIBRARIES "${_idi_cv_links}")
  list(APPEND OpenCV_LIBS opencv_${_idi_module})
endforeach()
