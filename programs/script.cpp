#include "ev3prog/script.hpp"

#include "ev3io/state_file.hpp"
#include "ev3prog/console.hpp"

namespace ev3prog {

std::string Script::load(const std::string& path) {
  std::vector<std::string> lines;
  std::string err;
  if (!ev3io::read_lines(path, lines, err)) return err.empty() ? "cannot open '" + path + "': no such file" : err;
  lines_ = std::move(lines);
  pos_ = lines_.size();  // not started
  return {};
}

bool Script::next(ev3proto::Millis now, std::string& line) {
  while (pos_ < lines_.size() && now >= at_) {
    const std::string& l = lines_[pos_++];
    ConsoleCommand c;
    if (parse_console_line(l, c).empty() && c.kind == ConsoleCommand::Kind::wait) {
      at_ = now + static_cast<ev3proto::Millis>(c.seconds * 1000.0);
      continue;
    }
    line = l;
    return true;
  }
  return false;
}

ev3proto::Millis Script::deadline() const { return pos_ < lines_.size() ? at_ : ~ev3proto::Millis{0}; }

}  // namespace ev3prog
