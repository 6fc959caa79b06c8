# Built against the ROS wheels from PyPI (the Makefile's rosidl_install): their exported CMake targets
# carry the include directory of the interpreter that built them (/opt/python/...).  Points them at
# the include directories in the variable named DIRS_VAR (this interpreter's Python and NumPy
# headers).  Not used by a colcon build on a full ROS install (the packages include it only when the
# Makefile defines that variable).
function(use_this_python_headers DIRS_VAR)
  set(_dirs ${${DIRS_VAR}})
  foreach(tgt Python3::Python Python3::Module Python3::NumPy)
    if(TARGET ${tgt})
      get_target_property(_aliased ${tgt} ALIASED_TARGET)
      if(NOT _aliased)
        set_target_properties(${tgt} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_dirs}")
      endif()
    endif()
  endforeach()
  get_property(_targets DIRECTORY PROPERTY IMPORTED_TARGETS)
  foreach(tgt ${_targets})
    get_target_property(_inc ${tgt} INTERFACE_INCLUDE_DIRECTORIES)
    if(_inc AND "${_inc}" MATCHES "/opt/python/")
      list(FILTER _inc EXCLUDE REGEX "/opt/python/")
      list(APPEND _inc ${_dirs})
      set_target_properties(${tgt} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_inc}")
    endif()
  endforeach()
endfunction()
