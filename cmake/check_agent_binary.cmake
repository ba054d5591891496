# The EV3 binary carries what the robot runs and no more (docs/benchmarks.md, "The EV3 binary"):
#   cmake -DAGENT=path/to/ev3-agent -DNM=arm-linux-gnueabi-nm -DSTRIP=arm-linux-gnueabi-strip
#         -DLIMIT=1500000 -P cmake/check_agent_binary.cmake
# Fails when the static ev3-agent is larger than LIMIT bytes (as built, not stripped), when it holds
# libstdc++'s iostreams (std::cin, getline on an istream, fstreams, stringstreams: about 530 KB with
# the locale machinery they pull), or when it compiles the agent core more than once.
foreach(v AGENT NM STRIP LIMIT)
  if(NOT DEFINED ${v})
    message(FATAL_ERROR "check_agent_binary: -D${v}=... is missing")
  endif()
endforeach()

file(SIZE "${AGENT}" size)
set(stripped_file "${AGENT}.stripped")
execute_process(COMMAND "${STRIP}" -o "${stripped_file}" "${AGENT}" RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "check_agent_binary: ${STRIP} failed on ${AGENT}")
endif()
file(SIZE "${stripped_file}" stripped)
file(REMOVE "${stripped_file}")
message(STATUS "ev3-agent: ${size} bytes (${stripped} stripped); limit ${LIMIT}")
set(failed "")
if(size GREATER LIMIT)
  string(APPEND failed "\n  ${size} bytes is more than ${LIMIT}")
endif()

execute_process(COMMAND "${NM}" -C "${AGENT}" OUTPUT_VARIABLE syms RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "check_agent_binary: ${NM} failed on ${AGENT}")
endif()
string(REGEX MATCHALL "[^\n]*(std::basic_istream|std::basic_ostream|std::basic_[io]?fstream|std::basic_[io]?stringstream|std::basic_filebuf|std::ios_base::Init|std::cin|std::cout|std::cerr)[^\n]*" ios "${syms}")
list(LENGTH ios n_ios)
if(n_ios GREATER 0)
  list(GET ios 0 first)
  string(APPEND failed "\n  ${n_ios} iostream symbols, the first: ${first}")
endif()

# Every distinct template argument list of ev3proto::Agent<...> whose members are in the binary.
string(REGEX MATCHALL "ev3proto::Agent<[^<>]*>::[A-Za-z_~]" members "${syms}")
set(cores "")
foreach(m IN LISTS members)
  string(REGEX REPLACE ">::[A-Za-z_~]$" ">" m "${m}")
  list(APPEND cores "${m}")
endforeach()
list(REMOVE_DUPLICATES cores)
list(LENGTH cores n_cores)
message(STATUS "ev3-agent: ${n_cores} agent core instantiation(s): ${cores}")
if(NOT n_cores EQUAL 1)
  string(APPEND failed "\n  ${n_cores} instantiations of the agent core (one expected): ${cores}")
endif()

if(failed)
  message(FATAL_ERROR "ev3-agent is not the robot's binary:${failed}")
endif()
