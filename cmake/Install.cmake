# What `cmake --install` and the Debian package (cmake/DebianPackage.cmake) put where. Paths
# under the prefix (/usr in the package) follow GNUInstallDirs; the system's own places are
# absolute, because systemd and the units look there whatever the prefix:
#   bin/dronetrack                 the executable
#   share/dronetrack/web/          the operator page; the executable finds it from its own path
#                                  (PREFIX/bin -> PREFIX/share/dronetrack, apps/data_paths.hpp)
#   share/dronetrack/scenarios/    the bundled simulator scenes (`demo`, `sim`)
#   share/dronetrack/examples/     example sites and Cyclone DDS configs, read-only
#   share/dronetrack/site-pki.sh   the DDS Security PKI maker (docs/deployment.md)
#   share/doc/dronetrack/          README.md and docs/
#   /etc/dronetrack/               what the units read, edited in place (conffiles): site.json
#                                  (the perimeter example to start from), cyclonedds.xml (the
#                                  network config), on-alert (the alert unit's program)
#   /lib/systemd/system/           the units (deploy/); they run /usr/bin/dronetrack
#   lib/sysusers.d/dronetrack.conf the system user, created by the package's postinst
include(GNUInstallDirs)

install(TARGETS dronetrack RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})

set(DRONETRACK_INSTALL_DATADIR ${CMAKE_INSTALL_DATADIR}/dronetrack)
install(DIRECTORY web/ DESTINATION ${DRONETRACK_INSTALL_DATADIR}/web
  FILES_MATCHING PATTERN "*.html" PATTERN "*.js" PATTERN "*.css" PATTERN "*.svg" PATTERN "*.png"
  PATTERN "test" EXCLUDE)
install(DIRECTORY config/scenarios/ DESTINATION ${DRONETRACK_INSTALL_DATADIR}/scenarios
  FILES_MATCHING PATTERN "*.json")
install(FILES config/site-perimeter.json config/site-seed002.json config/cyclonedds-network.xml
              config/cyclonedds-loopback.xml
  DESTINATION ${DRONETRACK_INSTALL_DATADIR}/examples)
install(PROGRAMS scripts/site-pki.sh DESTINATION ${DRONETRACK_INSTALL_DATADIR})
install(FILES README.md DESTINATION ${CMAKE_INSTALL_DOCDIR})
install(DIRECTORY docs/ DESTINATION ${CMAKE_INSTALL_DOCDIR})

# The conffiles: every file installed under /etc, and only those (the package test checks both).
set(DRONETRACK_CONFFILES
  /etc/dronetrack/site.json /etc/dronetrack/cyclonedds.xml /etc/dronetrack/on-alert)
install(FILES config/site-perimeter.json DESTINATION /etc/dronetrack RENAME site.json)
install(FILES config/cyclonedds-network.xml DESTINATION /etc/dronetrack RENAME cyclonedds.xml)
install(PROGRAMS deploy/on-alert DESTINATION /etc/dronetrack)

install(FILES deploy/dronetrack-node@.service deploy/dronetrack-fusion.service
              deploy/dronetrack-alert.service
  DESTINATION /lib/systemd/system)
install(FILES deploy/debian/dronetrack.sysusers DESTINATION lib/sysusers.d  # not multiarch: systemd reads PREFIX/lib/sysusers.d
  RENAME dronetrack.conf)
