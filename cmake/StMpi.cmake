# ST_WITH_MPI=AUTO builds `batch` and `search --mpi` with MPI when an MPI library is found (Debian:
# libopenmpi-dev), ON fails loudly without it, OFF skips it. Without MPI both commands run in one process.
set(ST_HAVE_MPI OFF)
if(NOT ST_WITH_MPI STREQUAL "OFF")
  find_package(MPI COMPONENTS CXX QUIET)
  if(MPI_CXX_FOUND)
    set(ST_HAVE_MPI ON)
    find_program(ST_MPIEXEC NAMES mpirun mpiexec HINTS ${MPI_HOME}/bin)
    # Open MPI derives its prefix from the path it was started by: /bin/mpirun (merged /usr on Debian) gives
    # the prefix "/", which it refuses ("a prefix ... that only contained slashes"). Use the real path.
    if(ST_MPIEXEC)
      file(REAL_PATH "${ST_MPIEXEC}" ST_MPIEXEC_REAL)
      set(ST_MPIEXEC "${ST_MPIEXEC_REAL}" CACHE FILEPATH "mpirun for the MPI tests" FORCE)
    endif()
    message(STATUS "synthtrack: MPI enabled (${MPI_CXX_LIBRARY_VERSION_STRING})")
  elseif(ST_WITH_MPI STREQUAL "ON")
    message(FATAL_ERROR "ST_WITH_MPI=ON but no MPI was found. Install it (Debian: apt-get install "
                        "libopenmpi-dev openmpi-bin) or use -DST_WITH_MPI=AUTO/OFF.")
  else()
    message(STATUS "synthtrack: no MPI found; batch runs in one process")
  endif()
endif()
