# Debian packages of the two binaries (CPack DEB, one package per component):
#   idi-rmp       /usr/bin/idi-rmp, idi-rmp.service, /etc/idi/rmp.yaml (conffile), man page, ...
#   idi-workcell  /usr/bin/idi-workcell, idi-workcell.service, /etc/idi/workcell.yaml, ...
# Each package creates its service's system user in postinst; state lives in /var/lib/<package>
# (the unit's StateDirectory). Build a tree (any preset), then `cpack --config <build>/CPackConfig.cmake`
# or tools/package-check. A cross build marks its package with the target's architecture
# (IDI_DEB_ARCHITECTURE from the toolchain file) and derives Depends itself (IdiCrossDepends.cmake).
include_guard(GLOBAL)

set(IDI_PACKAGING_DIR ${PROJECT_SOURCE_DIR}/packaging)
set(IDI_DEB_MAINTAINER "idi developers <idi-developers@example.org>")

if(NOT IDI_DEB_ARCHITECTURE)
  find_program(IDI_DPKG dpkg)
  if(IDI_DPKG)
    execute_process(COMMAND ${IDI_DPKG} --print-architecture OUTPUT_VARIABLE IDI_DEB_ARCHITECTURE
                    OUTPUT_STRIP_TRAILING_WHITESPACE)
  else()
    set(IDI_DEB_ARCHITECTURE amd64)
  endif()
endif()

# The configuration file a package installs: targets/<IDI_TARGET>/<file>, else the machine that
# usually runs that binary.
function(idi_target_config out file fallback_target)
  if(EXISTS ${PROJECT_SOURCE_DIR}/targets/${IDI_TARGET}/${file})
    set(${out} ${PROJECT_SOURCE_DIR}/targets/${IDI_TARGET}/${file} PARENT_SCOPE)
  else()
    set(${out} ${PROJECT_SOURCE_DIR}/targets/${fallback_target}/${file} PARENT_SCOPE)
  endif()
endfunction()

# idi_deb_package(<component> BINARY <target> CONFIG <yaml> SUMMARY <text> DESCRIPTION <text>)
function(idi_deb_package component)
  cmake_parse_arguments(ARG "" "BINARY;CONFIG;SUMMARY;DESCRIPTION" "" ${ARGN})
  set(pkg idi-${component})
  string(TOUPPER ${component} COMP)
  set(gen ${CMAKE_BINARY_DIR}/packaging/${pkg})
  file(MAKE_DIRECTORY ${gen})

  install(TARGETS ${ARG_BINARY} RUNTIME DESTINATION bin COMPONENT ${component})
  install(FILES ${PROJECT_SOURCE_DIR}/systemd/${pkg}.service DESTINATION /lib/systemd/system
          COMPONENT ${component})
  install(FILES ${PROJECT_SOURCE_DIR}/systemd/70-idi.rules DESTINATION /lib/udev/rules.d
          RENAME 70-${pkg}.rules COMPONENT ${component})
  install(FILES ${ARG_CONFIG} DESTINATION /etc/idi PERMISSIONS OWNER_READ OWNER_WRITE GROUP_READ WORLD_READ
          COMPONENT ${component})
  # Compressed documentation (Debian policy 12.3): man page, changelog, copyright.
  find_program(IDI_GZIP gzip REQUIRED)
  foreach(doc man/${pkg}.1 debian/changelog)
    get_filename_component(name ${doc} NAME)
    add_custom_command(OUTPUT ${gen}/${name}.gz
                       COMMAND ${IDI_GZIP} -9n -c ${IDI_PACKAGING_DIR}/${doc} > ${gen}/${name}.gz
                       DEPENDS ${IDI_PACKAGING_DIR}/${doc} VERBATIM)
  endforeach()
  add_custom_target(${pkg}-docs ALL DEPENDS ${gen}/${pkg}.1.gz ${gen}/changelog.gz)
  install(FILES ${gen}/${pkg}.1.gz DESTINATION share/man/man1 COMPONENT ${component})
  install(FILES ${gen}/changelog.gz ${IDI_PACKAGING_DIR}/debian/copyright DESTINATION share/doc/${pkg}
          COMPONENT ${component})
  if(EXISTS ${IDI_PACKAGING_DIR}/lintian/${pkg})
    install(FILES ${IDI_PACKAGING_DIR}/lintian/${pkg} DESTINATION share/lintian/overrides
            COMPONENT ${component})
  endif()

  # Maintainer scripts and conffiles.
  set(PKG ${pkg})
  set(USER ${pkg})
  foreach(script postinst prerm postrm)
    configure_file(${IDI_PACKAGING_DIR}/debian/${script}.in ${gen}/${script} @ONLY
                   FILE_PERMISSIONS OWNER_READ OWNER_WRITE OWNER_EXECUTE GROUP_READ GROUP_EXECUTE
                                    WORLD_READ WORLD_EXECUTE)
  endforeach()
  get_filename_component(config_name ${ARG_CONFIG} NAME)
  file(WRITE ${gen}/conffiles "/etc/idi/${config_name}\n")

  set(CPACK_DEBIAN_${COMP}_PACKAGE_NAME ${pkg} PARENT_SCOPE)
  set(CPACK_DEBIAN_${COMP}_FILE_NAME DEB-DEFAULT PARENT_SCOPE)
  set(CPACK_DEBIAN_${COMP}_PACKAGE_SECTION science PARENT_SCOPE)
  set(CPACK_DEBIAN_${COMP}_PACKAGE_CONTROL_EXTRA "${gen}/conffiles;${gen}/postinst;${gen}/prerm;${gen}/postrm"
      PARENT_SCOPE)
  set(CPACK_DEBIAN_${COMP}_DESCRIPTION "${ARG_SUMMARY}\n${ARG_DESCRIPTION}" PARENT_SCOPE)
  set(CPACK_DEBIAN_${COMP}_PACKAGE_DEPENDS "adduser" PARENT_SCOPE)
endfunction()

set(idi_components)
if(TARGET idi-rmp)
  idi_target_config(idi_rmp_config rmp.yaml segway-laptop)
  idi_deb_package(rmp BINARY idi-rmp CONFIG ${idi_rmp_config}
    SUMMARY "Segway RMP track follower with two fixed cameras (idi)"
    DESCRIPTION "idi-rmp finds the straight lines and intersection points of a track
taped on the ground in the images of two fixed cameras, triangulates
them onto the ground plane, plans a curved path that keeps the track in
view and drives a Segway RMP over CAN (SocketCAN). It runs as a systemd
service on the vehicle computer, and against the built-in simulation or
a recorded log on any machine."
)
  list(APPEND idi_components rmp)
endif()
if(TARGET idi-workcell)
  idi_target_config(idi_workcell_config workcell.yaml workcell-pc)
  idi_deb_package(workcell BINARY idi-workcell CONFIG ${idi_workcell_config}
    SUMMARY "Robot workcell calibration and reconstruction from lines and points (idi)"
    DESCRIPTION "idi-workcell controls two Staubli RX-130 arms on a rail, a pan-tilt
camera head, a laser pointer and a Barrett hand. It calibrates the arms
and the rail, calibrates the pan-tilt cameras from one unknown laser
spot, reconstructs objects from the straight lines and intersection
points seen from several views, and picks them. It runs as a systemd
service on the workcell PC."
)
  # The USB serial drivers at boot: the unit's DeviceAllow=char-ttyUSB/char-ttyACM find their majors in
  # /proc/devices when it starts, and an adapter enumerated later would be refused until a restart.
  install(FILES ${PROJECT_SOURCE_DIR}/systemd/idi-workcell-modules.conf DESTINATION /usr/lib/modules-load.d
          RENAME idi-workcell.conf COMPONENT workcell)
  list(APPEND idi_components workcell)
endif()

set(CPACK_GENERATOR DEB)
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_ALL ${idi_components})
set(CPACK_PACKAGE_NAME idi)
set(CPACK_PACKAGE_VENDOR "idi developers")
# Each package's synopsis is the first line of its own description (else CPack prepends the project's).
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_CONTACT "${IDI_DEB_MAINTAINER}")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)
set(CPACK_DEBIAN_PACKAGE_MAINTAINER "${IDI_DEB_MAINTAINER}")
set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE ${IDI_DEB_ARCHITECTURE})
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_PACKAGE_SOURCE idi)
set(CPACK_DEBIAN_COMPRESSION_TYPE xz)
# Native builds: dpkg-shlibdeps finds the library packages. Cross builds: dpkg-shlibdeps cannot read
# the sysroot, so at cpack time IdiCrossDepends.cmake maps the binary's DT_NEEDED libraries to the
# Debian packages that ship them (the same package names on every architecture).
if(CMAKE_CROSSCOMPILING)
  set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS OFF)
  find_program(IDI_CROSS_READELF ${IDI_CROSS_TRIPLET}-readelf REQUIRED)
  set(idi_cross_bins "")
  foreach(component ${idi_components})
    string(APPEND idi_cross_bins "set(IDI_CROSS_BINARY_${component} \"$<TARGET_FILE:idi-${component}>\")\n")
  endforeach()
  file(GENERATE OUTPUT ${CMAKE_BINARY_DIR}/packaging/cpack-project-config.cmake CONTENT
       "set(IDI_CROSS_READELF \"${IDI_CROSS_READELF}\")\nset(IDI_HOST_MULTIARCH \"${CMAKE_HOST_SYSTEM_PROCESSOR}-linux-gnu\")\nset(IDI_CROSS_SYSROOT \"${IDI_SYSROOT}\")\n${idi_cross_bins}include(\"${CMAKE_CURRENT_LIST_DIR}/IdiCrossDepends.cmake\")\n")
  set(CPACK_PROJECT_CONFIG_FILE ${CMAKE_BINARY_DIR}/packaging/cpack-project-config.cmake)
else()
  set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
endif()
include(CPack)
