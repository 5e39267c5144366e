# SPDX-License-Identifier: BSD-3-Clause
# Helpers shared by every cleanmap target.

# Warnings per target (not global, so third-party headers stay quiet as SYSTEM includes).
function(cleanmap_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor
                                           -Wno-psabi)
endfunction()

# cleanmap_library(<name> [NO_UNITY] SOURCES ... DEPS ...): builds cleanmap_<name>, alias cleanmap::<name>,
# public headers under include/, exported for install.
function(cleanmap_library name)
  cmake_parse_arguments(ARG "NO_UNITY" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(cleanmap_${name} ${ARG_SOURCES})
  add_library(cleanmap::${name} ALIAS cleanmap_${name})
  set_target_properties(cleanmap_${name} PROPERTIES EXPORT_NAME ${name}
                        VERSION ${PROJECT_VERSION} SOVERSION ${PROJECT_VERSION_MAJOR}.${PROJECT_VERSION_MINOR})
  target_include_directories(cleanmap_${name} PUBLIC
    $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include>
    $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  target_compile_features(cleanmap_${name} PUBLIC cxx_std_17)
  target_link_libraries(cleanmap_${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  cleanmap_warnings(cleanmap_${name})
  # Sources compiled 8 to a file (CMake's unity build): the libraries compile in half the time,
  # their shared headers parsed and their templates instantiated once per batch (doc/BENCHMARK.md,
  # fiftieth session). Files with their own flags (beam_filter.cpp, ...) stay apart.
  # gcc takes a batch's later files for headers and warns of their classes holding types of the
  # file's anonymous namespace (-Wsubobject-linkage); in a .cpp that is no fault. NO_UNITY: a
  # library whose files depend on their static initializers' order (libs/maps/CMakeLists.txt).
  if(CLEANMAP_UNITY_BUILD AND NOT ARG_NO_UNITY)
    set_target_properties(cleanmap_${name} PROPERTIES UNITY_BUILD ON UNITY_BUILD_BATCH_SIZE 8)
    if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
      target_compile_options(cleanmap_${name} PRIVATE -Wno-subobject-linkage)
    endif()
  endif()
  install(TARGETS cleanmap_${name} EXPORT cleanmapTargets
          LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
          ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
          RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
  install(DIRECTORY include/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
endfunction()

function(cleanmap_app name)
  add_executable(${name} ${ARGN})
  cleanmap_warnings(${name})
  install(TARGETS ${name} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
endfunction()
