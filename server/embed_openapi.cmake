# Writes OUT, a C++ source defining cutload::server::openapi_json() with the text of IN.
file(READ ${IN} text)
string(FIND "${text}" ")cutload_openapi\"" clash)
if(NOT clash EQUAL -1)
  message(FATAL_ERROR "${IN} contains the raw-string delimiter")
endif()
file(WRITE ${OUT} "// Generated from server/openapi.json by server/embed_openapi.cmake; do not edit.\n"
  "#include \"server/server.hpp\"\n"
  "namespace cutload::server {\n"
  "const std::string& openapi_json() {\n"
  "    static const std::string doc = R\"cutload_openapi(${text})cutload_openapi\";\n"
  "    return doc;\n"
  "}\n"
  "}  // namespace cutload::server\n")
