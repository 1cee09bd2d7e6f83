# The smoke tests' way to run the kdtrace executable, for every tests/*/tests.cmake
# (tests/CMakeLists.txt includes this file before them).

# kdt_status_test(NAME STATUS REGEX COMMAND...): the test NAME runs COMMAND with its stderr
# into its stdout, then prints "status N" with its exit status N, and passes when that text
# matches REGEX followed by "status STATUS". ctest ignores the exit status of a test that has
# a PASS_REGULAR_EXPRESSION, so without this an error path that exits 0, or a crash after the
# expected line, would pass. A REGEX ending in $ matches up to the end of the output; any
# other, some part of it.
function(kdt_status_test name status regex)
  # Each argument of COMMAND as given, in a bracket argument: ${ARGN} would drop an empty one
  # and split one at a ";" that no "[" precedes.
  set(_command "")
  math(EXPR _last "${ARGC} - 1")
  foreach(_i RANGE 3 ${_last})
    string(APPEND _command " [==[${ARGV${_i}}]==]")
  endforeach()
  cmake_language(EVAL CODE
    "add_test(NAME ${name} COMMAND sh -c [==[\"$@\" 2>&1; echo \"status $?\"]==] sh${_command})")
  # A ";" in a property is a list separator (the halves would pass on their own) unless
  # bracketed.
  string(REPLACE ";" "[;]" regex "${regex}")
  if(regex MATCHES "\\$$")
    string(REGEX REPLACE "\\$$" "status ${status}\n$" regex "${regex}")
  else()
    string(APPEND regex "(.*\n)?status ${status}\n$")
  endif()
  set_tests_properties(${name} PROPERTIES PASS_REGULAR_EXPRESSION "${regex}")
endfunction()
