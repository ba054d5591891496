/// @file behaviour/dot.hpp
/// @brief to_dot(): a behaviour's automaton for Graphviz. States are boxes (the normal course in bold),
/// the start is marked by an arrow from a dot, the stop state is a double octagon; default transitions
/// are solid, reactions dashed and labelled with their event or condition; `ignore`d events are listed
/// in the state; a note gives the params and the report. The failure of an action (to the stop state,
/// the runtime's rule) is not drawn: every state has it.
#pragma once

#include <cstdint>

#include "definition.hpp"
#include "print.hpp"

namespace ev3proto::behaviour {

inline void to_dot(Text& out, const Definition& def) {
  bool normal[kMaxStates] = {};
  for (std::uint8_t s = def.start; s != kNone && !normal[s]; s = def.states[s].next) normal[s] = true;

  out << "digraph \"" << def.name.view() << "\" {\n"
      << "  graph [rankdir=LR, fontname=\"Helvetica\", fontsize=12, labelloc=t, label=\"behaviour "
      << def.name.view() << "\"];\n"
      << "  node [shape=box, style=rounded, fontname=\"Helvetica\", fontsize=11];\n"
      << "  edge [fontname=\"Helvetica\", fontsize=9];\n";
  if (def.param_count > 0 || def.report.count > 0) {
    out << "  _params [shape=note, style=\"\", fontsize=9, label=\"";
    for (std::uint8_t i = 0; i < def.param_count; ++i) {
      const Param& p = def.params[i];
      out << p.name.view() << " = ";
      write(out, p);
      out << "\\l";
    }
    if (def.report.count > 0) {
      out << "report ";
      for (std::uint8_t i = 0; i < def.report.count; ++i) out << (i ? ", " : "") << to_string(def.report.sensors[i]);
      out << " every ";
      write(out, def.report.period);
      out << "\\l";
    }
    out << "\"];\n";
  }
  out << "  _start [shape=point, width=0.12, label=\"\"];\n"
      << "  _start -> \"" << def.states[def.start].name.view() << "\";\n";
  for (std::uint8_t s = 0; s < def.state_count; ++s) {
    const State& st = def.states[s];
    out << "  \"" << st.name.view() << "\" [label=\"" << st.name.view() << "\\n";
    write_action(out, def, st, ", ", true);
    if (s == def.stop) out << "\\n(also after a failed action)";
    bool first = true;
    for (std::uint8_t e = 0; e < robot::kEventKindCount && s != def.stop; ++e) {
      const Reaction* r = def.on_event(s, static_cast<EventKind>(e));
      if (r == nullptr || r->target != kIgnore) continue;
      out << (first ? "\\nignores " : ", ") << to_string(static_cast<EventKind>(e));
      first = false;
    }
    out << '"';
    if (s == def.stop) out << ", shape=doubleoctagon, style=\"\"";
    else if (normal[s]) out << ", style=\"rounded,bold\"";
    out << "];\n";
  }
  auto edge = [&](std::uint8_t from, const Reaction& r) {
    out << "  \"" << def.states[from].name.view() << "\" -> \"" << def.states[r.target].name.view()
        << "\" [style=dashed, label=\"";
    write_trigger(out, def, r);
    out << "\"];\n";
  };
  for (std::uint8_t s = 0; s < def.state_count; ++s) {
    const State& st = def.states[s];
    if (st.next != kNone)
      out << "  \"" << st.name.view() << "\" -> \"" << def.states[st.next].name.view() << "\";\n";
    if (s == def.stop) continue;
    for (std::uint8_t k = 0; k < st.reaction_count; ++k) {
      const Reaction& r = def.reactions[st.first_reaction + k];
      if (r.target != kIgnore) edge(s, r);
    }
    for (std::uint8_t k = 0; k < def.global_reactions; ++k) {
      const Reaction& r = def.reactions[k];
      if (r.target == kIgnore || (r.trigger == Trigger::event && def.on_event(s, r.event) != &r)) continue;
      edge(s, r);
    }
  }
  out << "}\n";
}

}  // namespace ev3proto::behaviour
