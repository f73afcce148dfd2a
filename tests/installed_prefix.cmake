# Installs the build into PREFIX (emptied first) and runs the paper's case
# with the installed binary and input, from a folder outside the sources.
file(REMOVE_RECURSE ${PREFIX})
execute_process(COMMAND ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${PREFIX} RESULT_VARIABLE rc OUTPUT_QUIET)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "cmake --install failed (${rc})")
endif()
foreach(path bin/ellroll share/ellroll/input/legeza1990.nml share/ellroll/examples/paper_case.sh
        share/doc/ellroll/README.md share/doc/ellroll/LICENSE share/doc/ellroll/docs/model.md share/doc/ellroll/post/README.md
        share/bash-completion/completions/ellroll)
  if(NOT EXISTS ${PREFIX}/${path})
    message(FATAL_ERROR "not installed: ${path}")
  endif()
endforeach()
file(MAKE_DIRECTORY ${PREFIX}/run)
execute_process(COMMAND ${PREFIX}/bin/ellroll run ${PREFIX}/share/ellroll/input/legeza1990.nml -o paper.h5 -q
                WORKING_DIRECTORY ${PREFIX}/run RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0 OR NOT EXISTS ${PREFIX}/run/paper.h5)
  message(FATAL_ERROR "the installed ellroll failed on the paper's case (${rc}): ${err}")
endif()
if(NOT out MATCHES "completed +1" OR NOT out MATCHES "theta_max: 0\\.234")
  message(FATAL_ERROR "unexpected summary of the paper's case:\n${out}")
endif()
