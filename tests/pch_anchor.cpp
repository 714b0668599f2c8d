// The source of each test suite's precompiled-header target (tests/CMakeLists.txt, st_<suite>_pch): the
// header is built with it and reused by the suite's tests; this file itself defines nothing.
