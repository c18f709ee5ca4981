# Installation rules and the Debian package (CPack's DEB generator): `cpack -G DEB` in the build
# directory (or `cmake --build build --target package`) writes odonav_<version>_<arch>.deb.
#
# With the default prefix /usr the package holds:
#   /usr/bin/odonav-*                       the five pipeline components, the ground station, the
#                                           offline tool, evaluation, simulator and report
#   /etc/odonav/profiles/*.xml              the Fast DDS profiles (conffiles)
#   /etc/odonav/vehicle.env                 what differs between vehicles and ECUs (conffile)
#   /usr/lib/systemd/system/odonav*.service, odonav.target   (ExecStart in /usr/bin)
#   /usr/share/odonav/security/             the DDS Security tooling (make-pki, governance, grants)
#   /usr/share/doc/odonav/                  README, docs/, deploy/README.md, copyright
# Depends are computed from the shared libraries (dpkg-shlibdeps). The maintainer scripts
# (deploy/debian/) create the system user odonav and never enable or start a unit; purge removes the
# user, /var/lib/odonav and /etc/odonav.
# A Debian package installs under /usr (its /etc files then go to /etc): the default prefix when none
# was given (-DCMAKE_INSTALL_PREFIX=... still wins, e.g. /usr/local for `cmake --install` by hand).
if(CMAKE_INSTALL_PREFIX_INITIALIZED_TO_DEFAULT)
  set(CMAKE_INSTALL_PREFIX /usr CACHE PATH "Install prefix" FORCE)
endif()
include(GNUInstallDirs)

set(_odonav_programs odonav-gateway odonav-calibration odonav-identification odonav-dead-reckoning
  odonav-recorder odonav-ground odonav-offline odonav-evaluate odonav-simulator)
install(TARGETS ${_odonav_programs} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(PROGRAMS ${CMAKE_SOURCE_DIR}/components/report/odonav-report DESTINATION ${CMAKE_INSTALL_BINDIR})

# /etc when the prefix is /usr (GNUInstallDirs' rule), PREFIX/etc otherwise.
set(_odonav_etc ${CMAKE_INSTALL_FULL_SYSCONFDIR}/odonav)
file(GLOB _odonav_profiles ${CMAKE_SOURCE_DIR}/deploy/profiles/*.xml)
install(FILES ${_odonav_profiles} DESTINATION ${_odonav_etc}/profiles)
install(FILES ${CMAKE_SOURCE_DIR}/deploy/systemd/vehicle.env.example DESTINATION ${_odonav_etc} RENAME vehicle.env)

# The units name the installed binaries and documents.
file(GLOB _odonav_units ${CMAKE_SOURCE_DIR}/deploy/systemd/*.service ${CMAKE_SOURCE_DIR}/deploy/systemd/*.target)
foreach(_unit ${_odonav_units})
  get_filename_component(_name ${_unit} NAME)
  file(READ ${_unit} _text)
  string(REPLACE "/usr/local/bin/" "${CMAKE_INSTALL_FULL_BINDIR}/" _text "${_text}")
  string(REPLACE "/usr/local/share/doc/odonav/" "${CMAKE_INSTALL_FULL_DOCDIR}/" _text "${_text}")
  file(WRITE ${CMAKE_BINARY_DIR}/systemd/${_name} "${_text}")
  install(FILES ${CMAKE_BINARY_DIR}/systemd/${_name} DESTINATION lib/systemd/system)  # not LIBDIR: no multiarch for units
endforeach()

install(PROGRAMS ${CMAKE_SOURCE_DIR}/deploy/security/make-pki DESTINATION ${CMAKE_INSTALL_DATADIR}/odonav/security)
install(FILES ${CMAKE_SOURCE_DIR}/deploy/security/governance.xml ${CMAKE_SOURCE_DIR}/deploy/security/permissions.xml.in
  DESTINATION ${CMAKE_INSTALL_DATADIR}/odonav/security)
install(FILES ${CMAKE_SOURCE_DIR}/deploy/security/grants DESTINATION ${CMAKE_INSTALL_DATADIR}/odonav/security)
install(FILES ${CMAKE_SOURCE_DIR}/README.md DESTINATION ${CMAKE_INSTALL_DOCDIR})
install(FILES ${CMAKE_SOURCE_DIR}/deploy/README.md DESTINATION ${CMAKE_INSTALL_DOCDIR}/deploy)
file(GLOB _odonav_docs ${CMAKE_SOURCE_DIR}/docs/*.md)
install(FILES ${_odonav_docs} DESTINATION ${CMAKE_INSTALL_DOCDIR}/docs)
install(FILES ${CMAKE_SOURCE_DIR}/deploy/debian/copyright DESTINATION ${CMAKE_INSTALL_DOCDIR})

set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME odonav)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
# The Maintainer field: set it to the team that ships the package to the vehicles.
set(ODONAV_PACKAGE_MAINTAINER "odonav maintainers <odonav@example.com>" CACHE STRING "Debian package Maintainer")
set(CPACK_PACKAGE_CONTACT "${ODONAV_PACKAGE_MAINTAINER}")
# A native package's changelog (Debian policy 12.7), compressed reproducibly (gzip -n).
configure_file(${CMAKE_SOURCE_DIR}/deploy/debian/changelog.in ${CMAKE_BINARY_DIR}/debian/changelog @ONLY)
execute_process(COMMAND gzip -9nf ${CMAKE_BINARY_DIR}/debian/changelog)
install(FILES ${CMAKE_BINARY_DIR}/debian/changelog.gz DESTINATION ${CMAKE_INSTALL_DOCDIR})
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "online odometer calibration and dead reckoning for tracked and wheeled vehicles")
set(CPACK_PACKAGE_DESCRIPTION "A SINS/OD navigator: calibrates the odometer-to-INS misalignment and
identifies the odometer scale factor online from GNSS, and dead-reckons
when GNSS is lost. Five Fast DDS processes (gateway, calibration,
identification, dead reckoning, recorder), a ground station, and the
offline tool that runs the same components on a recorded drive.")
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_STRIP_FILES ON)
# adduser for the maintainer scripts; `fastdds shm clean` (the units' ExecStartPre) and the report's
# figures are optional.
set(CPACK_DEBIAN_PACKAGE_DEPENDS "adduser")
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "fastdds-tools, python3, python3-matplotlib")
set(CPACK_PACKAGING_INSTALL_PREFIX ${CMAKE_INSTALL_PREFIX})
# Every file the package puts under /etc is a conffile: an upgrade keeps a user's edits.
set(_odonav_conffiles "${_odonav_etc}/vehicle.env\n")
foreach(_profile ${_odonav_profiles})
  get_filename_component(_name ${_profile} NAME)
  string(APPEND _odonav_conffiles "${_odonav_etc}/profiles/${_name}\n")
endforeach()
file(WRITE ${CMAKE_BINARY_DIR}/debian/conffiles "${_odonav_conffiles}")
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA
  ${CMAKE_SOURCE_DIR}/deploy/debian/postinst ${CMAKE_SOURCE_DIR}/deploy/debian/postrm ${CMAKE_BINARY_DIR}/debian/conffiles)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
include(CPack)
