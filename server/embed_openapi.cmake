# Writes OUT, a C++ source defining cutload::server::openapi_base() with the text of IN (the OpenAPI
# document without its parameters, which are generated from the route declarations).
file(READ ${IN} text)
string(FIND "${text}" ")cutload_openapi\"" clash)
if(NOT clash EQUAL -1)
  message(FATAL_ERROR "${IN} contains the raw-string delimiter")
endif()
file(WRITE ${OUT} "// Generated from server/openapi.json by server/embed_openapi.cmake; do not edit.\n"
  "#include <string>\n"
  "namespace cutload::server {\n"
  "const std::string& openapi_base();\n"
  "const std::string& openapi_base() {\n"
  "    static const std::string doc = R\"cutload_openapi(${text})cutload_openapi\";\n"
  "    return doc;\n"
  "}\n"
  "}  // namespace cutload::server\n")
