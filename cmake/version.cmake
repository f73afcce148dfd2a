# Writes version.f90 from `git describe`; run at every build, rewrites only on change.
execute_process(COMMAND git describe --tags --always --dirty
                WORKING_DIRECTORY ${SOURCE_DIR}
                OUTPUT_VARIABLE ELLROLL_VERSION
                OUTPUT_STRIP_TRAILING_WHITESPACE
                ERROR_QUIET RESULT_VARIABLE rc)
if(NOT rc EQUAL 0 OR ELLROLL_VERSION STREQUAL "")
  set(ELLROLL_VERSION "${FALLBACK_VERSION}")
else()
  set(ELLROLL_VERSION "${FALLBACK_VERSION}+git.${ELLROLL_VERSION}")
endif()
set(ELLROLL_BUILD "${BUILD}")
configure_file(${SOURCE_DIR}/src/app/version.f90.in ${OUTPUT} @ONLY)
