# ST_WITH_MPI=AUTO builds `batch` and `search --mpi` with MPI when an MPI library is found (Debian:
# libopenmpi-dev), ON fails loudly without it, OFF skips it. Without MPI both commands run in one process.
set(ST_HAVE_MPI OFF)
if(NOT ST_WITH_MPI STREQUAL "OFF")
  find_package(MPI COMPONENTS CXX QUIET)
  if(MPI_CXX_FOUND)
    set(ST_HAVE_MPI ON)
    find_program(ST_MPIEXEC NAMES mpirun mpiexec HINTS ${MPI_HOME}/bin)
    message(STATUS "synthtrack: MPI enabled (${MPI_CXX_LIBRARY_VERSION_STRING})")
  elseif(ST_WITH_MPI STREQUAL "ON")
    message(FATAL_ERROR "ST_WITH_MPI=ON but no MPI was found. Install it (Debian: apt-get install "
                        "libopenmpi-dev openmpi-bin) or use -DST_WITH_MPI=AUTO/OFF.")
  else()
    message(STATUS "synthtrack: no MPI found; batch runs in one process")
  endif()
endif()
