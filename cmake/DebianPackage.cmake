# The Debian package (issue 19): `cmake --build --preset release --target package` (or
# scripts/package-deb.sh) writes dronetrack_<version>_<arch>.deb into the build folder from the
# install rules of cmake/Install.cmake. CPack runs only on that request: configuring writes
# CPackConfig.cmake and nothing joins the `all` target.
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME dronetrack)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_CONTACT "dronetrack developers <dronetrack@invalid>")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES TRUE)  # the Release binary without its symbol table
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)  # dronetrack_0.1.0_amd64.deb
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_DESCRIPTION
  "acoustic drone tracking: array nodes, fusion, alerts, operator page
Tetrahedral microphone arrays measure directions of arrival (GCC-PHAT, least
squares); a fusion node tracks every drone with an Unscented Kalman Filter and
raises zone alerts. Nodes, fusion and subscribers talk over Cyclone DDS; the
fusion serves a web page. Recordings replay through the same code.
.
Ships the dronetrack executable, systemd units for nodes, fusion and alerts
(not enabled), their configuration in /etc/dronetrack and the web page.")
# Depends from the executable's shared libraries (dpkg-shlibdeps, dpkg-dev): FFTW, libsndfile,
# Cyclone DDS, PortAudio, OpenSSL, Highway, what the static Ceres needs, ... at the versions of
# the build machine.
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS systemd)  # the units, and systemd-sysusers for the user
# openssl: site-pki.sh; cyclonedds-tools: ddsperf, to check the network (docs/deployment.md).
set(CPACK_DEBIAN_PACKAGE_SUGGESTS "openssl, cyclonedds-tools")

list(JOIN DRONETRACK_CONFFILES "\n" conffiles)
file(WRITE ${PROJECT_BINARY_DIR}/debian/conffiles "${conffiles}\n")
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA
  ${PROJECT_BINARY_DIR}/debian/conffiles ${PROJECT_SOURCE_DIR}/deploy/debian/postinst
  ${PROJECT_SOURCE_DIR}/deploy/debian/prerm ${PROJECT_SOURCE_DIR}/deploy/debian/postrm)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION TRUE)  # scripts 0755, conffiles 0644
include(CPack)
