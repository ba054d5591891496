# Toolchain for the LEGO EV3 (ARM926EJ-S, ARMv5TE, soft float, ev3dev/armel): static binaries that
# run on the brick and, on a PC, under qemu-arm.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR arm)
set(CMAKE_C_COMPILER arm-linux-gnueabi-gcc)
set(CMAKE_CXX_COMPILER arm-linux-gnueabi-g++)
# Each function and object in its own section, and the linker drops the sections nothing uses: the
# brick's binary carries only what the agent can reach (e.g. of the console, only what an elected
# agent's --master-script runs).
set(CMAKE_C_FLAGS_INIT "-march=armv5te -mtune=arm926ej-s -mfloat-abi=soft -ffunction-sections -fdata-sections")
set(CMAKE_CXX_FLAGS_INIT "-march=armv5te -mtune=arm926ej-s -mfloat-abi=soft -Wno-psabi -ffunction-sections -fdata-sections")
# --discard-all: no local (file-static) symbols in the symbol table (120 KB of names, most of them
# glibc's and libsodium's); the global and template ones stay, for nm and for backtraces.
set(CMAKE_EXE_LINKER_FLAGS_INIT "-static -Wl,--gc-sections -Wl,--discard-all")
set(CMAKE_FIND_ROOT_PATH /usr/arm-linux-gnueabi)
# Debian's multiarch name: where the armel packages of libraries (libsodium-dev:armel) install.
set(EV3_MULTIARCH arm-linux-gnueabi)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
# Tests built with this toolchain run under qemu-arm.
set(CMAKE_CROSSCOMPILING_EMULATOR qemu-arm)
