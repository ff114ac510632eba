# Run by cpack (CPACK_PROJECT_CONFIG_FILE) for a cross build: dpkg-shlibdeps cannot resolve libraries
# in a sysroot, so this maps each DT_NEEDED library of a component's binary to the Debian package
# that ships it. Library package names are the same on every architecture, so the lookup uses this
# machine's dpkg database (the build dependencies are installed natively too); the version bound is
# that package's upstream version, without the Debian revision, so any bookworm point release
# satisfies it. Sets CPACK_DEBIAN_<COMPONENT>_PACKAGE_DEPENDS.
foreach(idi_component rmp workcell)
  if(NOT DEFINED IDI_CROSS_BINARY_${idi_component})
    continue()
  endif()
  string(TOUPPER ${idi_component} idi_comp)
  execute_process(COMMAND ${IDI_CROSS_READELF} -d ${IDI_CROSS_BINARY_${idi_component}}
                  OUTPUT_VARIABLE idi_dynamic RESULT_VARIABLE idi_rc)
  if(NOT idi_rc EQUAL 0)
    message(FATAL_ERROR "readelf -d ${IDI_CROSS_BINARY_${idi_component}} failed")
  endif()
  string(REGEX MATCHALL "Shared library: \\[[^]]+\\]" idi_needed "${idi_dynamic}")
  set(idi_depends adduser)
  foreach(idi_entry ${idi_needed})
    string(REGEX REPLACE "Shared library: \\[([^]]+)\\]" "\\1" idi_soname "${idi_entry}")
    execute_process(COMMAND dpkg-query -S "*/${IDI_HOST_MULTIARCH}/${idi_soname}"
                    OUTPUT_VARIABLE idi_owner
                    RESULT_VARIABLE idi_rc ERROR_QUIET)
    string(REGEX MATCH "^[^:,]+" idi_pkg "${idi_owner}")
    if(NOT idi_rc EQUAL 0 OR NOT idi_pkg)
      message(FATAL_ERROR "no installed package ships ${idi_soname} (needed by idi-${idi_component}); "
                          "install the native build dependencies (tools/install-deps)")
    endif()
    execute_process(COMMAND dpkg-query -W -f=\${Version} ${idi_pkg} OUTPUT_VARIABLE idi_version)
    string(REGEX REPLACE "-[^-]*$" "" idi_version "${idi_version}")  # drop the Debian revision
    list(APPEND idi_depends "${idi_pkg} (>= ${idi_version})")
  endforeach()
  list(REMOVE_DUPLICATES idi_depends)
  list(SORT idi_depends)
  list(JOIN idi_depends ", " idi_depends)
  set(CPACK_DEBIAN_${idi_comp}_PACKAGE_DEPENDS "${idi_depends}")
  message(STATUS "idi-${idi_component} (${CPACK_DEBIAN_PACKAGE_ARCHITECTURE}) Depends: ${idi_depends}")
endforeach()
