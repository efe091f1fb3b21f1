# OpenCV from Debian's component packages (libopencv-core-dev, -imgproc-dev,
# -imgcodecs-dev). They ship no OpenCVConfig.cmake (only the full
# libopencv-dev does), so the imported targets are made here.
find_path(ARTMS_OPENCV_INCLUDE_DIR opencv2/core.hpp PATH_SUFFIXES opencv4 REQUIRED)
foreach(component core imgproc imgcodecs)
  find_library(ARTMS_OPENCV_${component}_LIBRARY NAMES opencv_${component} REQUIRED)
  if(NOT TARGET artms::opencv_${component})
    add_library(artms::opencv_${component} UNKNOWN IMPORTED)
    set_target_properties(artms::opencv_${component} PROPERTIES
      IMPORTED_LOCATION ${ARTMS_OPENCV_${component}_LIBRARY}
      INTERFACE_INCLUDE_DIRECTORIES ${ARTMS_OPENCV_INCLUDE_DIR})
  endif()
endforeach()
