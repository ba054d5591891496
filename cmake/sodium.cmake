# libsodium, the MAC of signed datagrams (ev3proto/auth.hpp): Debian's libsodium-dev natively,
# libsodium-dev:armel (its static libsodium.a) for the EV3. Its headers do not depend on the
# architecture; the cross compiler sees them alone (links to them in the build directory), not the
# rest of the host's /usr/include.
if(CMAKE_CROSSCOMPILING)
  find_library(EV3_SODIUM_LIB NAMES libsodium.a PATHS /usr/lib/${EV3_MULTIARCH}
               NO_DEFAULT_PATH NO_CMAKE_FIND_ROOT_PATH)
  set(EV3_SODIUM_INCLUDE ${CMAKE_BINARY_DIR}/sodium-include)
  file(MAKE_DIRECTORY ${EV3_SODIUM_INCLUDE})
  file(CREATE_LINK /usr/include/sodium.h ${EV3_SODIUM_INCLUDE}/sodium.h SYMBOLIC)
  file(CREATE_LINK /usr/include/sodium ${EV3_SODIUM_INCLUDE}/sodium SYMBOLIC)
else()
  find_library(EV3_SODIUM_LIB NAMES sodium)
endif()
if(NOT EV3_SODIUM_LIB)
  message(FATAL_ERROR "libsodium not found (Debian: libsodium-dev, for armel libsodium-dev:armel; make deps installs them)")
endif()
add_library(ev3_sodium INTERFACE)
target_link_libraries(ev3_sodium INTERFACE ${EV3_SODIUM_LIB})
if(EV3_SODIUM_INCLUDE)
  target_include_directories(ev3_sodium SYSTEM INTERFACE ${EV3_SODIUM_INCLUDE})
endif()
