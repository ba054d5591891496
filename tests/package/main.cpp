// Everything the installed package must provide: the headers, the generated built-ins and PEGTL.
#include <ev3proto/robot_link.hpp>
int main() { return std::size(ev3proto::behaviour::kBuiltins) > 0 ? 0 : 1; }
