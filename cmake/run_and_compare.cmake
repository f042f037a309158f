# cmake -DEXE=program -DEXPECTED=file -P run_and_compare.cmake: runs EXE, compares its stdout.
execute_process(COMMAND ${EXE} OUTPUT_VARIABLE out RESULT_VARIABLE rc)
file(READ ${EXPECTED} expected)
if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${EXE} exited with ${rc}")
endif()
if(NOT out STREQUAL expected)
    message(FATAL_ERROR "${EXE} printed:\n${out}\nexpected:\n${expected}")
endif()
