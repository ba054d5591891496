# What `cmake --install` puts under the prefix for a firmware project out of this tree
# (docs/embedding.md). The library is header-only: nothing is compiled to install it.
#   include/ev3proto/...                    every header of libev3proto/include, and the generated
#                                           ev3proto/behaviour/builtins_text.hpp (cmake/behaviour.cmake)
#   share/cmake/ev3proto/                   the package: find_package(ev3proto), target ev3proto::ev3proto,
#                                           and the armel toolchain file (arm-linux-gnueabi.cmake)
#   share/pkgconfig/ev3proto.pc             the same for pkg-config
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(EV3_PACKAGE_DIR ${CMAKE_INSTALL_DATADIR}/cmake/ev3proto)

install(DIRECTORY libev3proto/include/ev3proto DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
        FILES_MATCHING PATTERN "*.hpp")
install(FILES ${EV3_GENERATED_INCLUDE}/ev3proto/behaviour/builtins_text.hpp
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/ev3proto/behaviour)

# The installed target is the in-tree `ev3proto` (C++17, the headers); its PEGTL comes from
# ev3proto-config.cmake, which finds PEGTL on the consumer's machine.
target_include_directories(ev3proto INTERFACE $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
install(TARGETS ev3proto EXPORT ev3proto-targets)
install(EXPORT ev3proto-targets NAMESPACE ev3proto:: DESTINATION ${EV3_PACKAGE_DIR})
configure_package_config_file(cmake/ev3proto-config.cmake.in ${CMAKE_BINARY_DIR}/ev3proto-config.cmake
                              INSTALL_DESTINATION ${EV3_PACKAGE_DIR})
write_basic_package_version_file(${CMAKE_BINARY_DIR}/ev3proto-config-version.cmake
                                 COMPATIBILITY SameMinorVersion ARCH_INDEPENDENT)
install(FILES ${CMAKE_BINARY_DIR}/ev3proto-config.cmake ${CMAKE_BINARY_DIR}/ev3proto-config-version.cmake
              cmake/arm-linux-gnueabi.cmake
        DESTINATION ${EV3_PACKAGE_DIR})

# pkg-config: the prefix is found from the .pc file's own place (${pcfiledir}), so the file stays
# right for `cmake --install --prefix DIR` and a moved tree.
set(EV3_PC_DIR ${CMAKE_INSTALL_DATADIR}/pkgconfig)
file(RELATIVE_PATH EV3_PC_TO_PREFIX /${EV3_PC_DIR} /)
string(REGEX REPLACE "/$" "" EV3_PC_TO_PREFIX "${EV3_PC_TO_PREFIX}")
configure_file(cmake/ev3proto.pc.in ${CMAKE_BINARY_DIR}/ev3proto.pc @ONLY)
install(FILES ${CMAKE_BINARY_DIR}/ev3proto.pc DESTINATION ${EV3_PC_DIR})
