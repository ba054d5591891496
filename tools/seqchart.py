#!/usr/bin/env python3
"""Draw a TLC error trace as a sequence chart (SVG): nodes as lifelines, datagrams as arrows.

Input: TLC's text output (the "Error: The behavior up to this point is:" trace).  The model must have
  - a variable holding the datagrams in flight (default `net`): a set of records with a sender and a
    receiver field (default `src`, `dst`; receiver 0 = broadcast, drawn to every other lifeline);
  - a variable with the last action and its arguments (default `lastAction`), a tuple <<name, ...>>;
  - a function variable whose domain are the lifelines (default `phase`); its value per node is drawn
    as a box on the lifeline whenever it changes.
A datagram is *sent* at the step where it appears in the net.  It is *delivered* at the step whose
lastAction carries it as an argument, or where it leaves the net by an action not named Lose*/Drop*;
it is *lost* where it leaves the net by a Lose*/Drop* action, and drawn as an arrow ending in a cross.
A datagram still in flight at the end is drawn dashed to the right margin.

Only the Python 3 standard library.  Usage:
  tools/seqchart.py TRACE.out OUT.svg [--net net] [--action lastAction] [--lifelines phase]
        [--src src] [--dst dst] [--label type,count] [--names 2=A,3=B] [--title TEXT]
"""
import argparse
import html
import re
import sys


# ---------------------------------------------------------------- TLC value parser
class Parser:
    TOKEN = re.compile(r'\s*(<<|>>|\|->|:>|@@|\\o|[\[\]{}(),:]|"(?:[^"\\]|\\.)*"|-?\d+|[A-Za-z_][A-Za-z0-9_]*)')

    def __init__(self, text):
        self.toks = []
        pos = 0
        text = text.strip()
        while pos < len(text):
            m = self.TOKEN.match(text, pos)
            if not m:
                raise ValueError("cannot parse TLC value near: %r" % text[pos:pos + 40])
            self.toks.append(m.group(1))
            pos = m.end()
            while pos < len(text) and text[pos].isspace():
                pos += 1
        self.i = 0

    def peek(self):
        return self.toks[self.i] if self.i < len(self.toks) else None

    def take(self, want=None):
        t = self.peek()
        if want is not None and t != want:
            raise ValueError("expected %r, got %r" % (want, t))
        self.i += 1
        return t

    def value(self):
        v = self.atom()
        # function literal: a :> b @@ c :> d
        if self.peek() == ':>':
            f = {}
            self.take(':>')
            f[freeze(v)] = self.atom()
            while self.peek() == '@@':
                self.take('@@')
                k = self.atom()
                self.take(':>')
                f[freeze(k)] = self.atom()
            return f
        return v

    def atom(self):
        t = self.take()
        if t == '(':
            v = self.value()
            self.take(')')
            return v
        if t == '<<':
            items = []
            while self.peek() != '>>':
                items.append(self.value())
                if self.peek() == ',':
                    self.take(',')
            self.take('>>')
            return tuple(items)
        if t == '{':
            items = []
            while self.peek() != '}':
                items.append(self.value())
                if self.peek() == ',':
                    self.take(',')
            self.take('}')
            return frozenset(freeze(x) for x in items)
        if t == '[':
            rec = {}
            while self.peek() != ']':
                k = self.take()
                self.take('|->')
                rec[k] = self.value()
                if self.peek() == ',':
                    self.take(',')
            self.take(']')
            return Rec(rec)
        if t.startswith('"'):
            return t[1:-1]
        if re.fullmatch(r'-?\d+', t):
            return int(t)
        if t in ('TRUE', 'FALSE'):
            return t == 'TRUE'
        return t  # a model value


class Rec(dict):
    def __hash__(self):
        return hash(tuple(sorted((k, freeze(v)) for k, v in self.items())))


def freeze(v):
    if isinstance(v, dict) and not isinstance(v, Rec):
        return tuple(sorted(v.items(), key=repr))
    return v


def parse_trace(text):
    """Return the list of states (dict var -> value) of the first error trace in TLC's output."""
    states = []
    cur = None
    var = None
    buf = []

    def flush():
        if cur is not None and var is not None:
            cur[var] = Parser(' '.join(buf)).value()

    started = False
    for line in text.splitlines():
        if line.startswith('Error: The behavior up to this point is:') or \
           line.startswith('Error: The following behavior constitutes'):
            started = True
            continue
        if not started:
            continue
        if re.match(r'^State \d+:', line) or re.match(r'^\d+: (Stuttering|Back to state)', line):
            flush()
            var = None
            buf = []
            if line.startswith('State'):
                cur = {}
                states.append(cur)
            else:
                cur = None
            continue
        m = re.match(r'^/\\ (\w+) = (.*)$', line)
        if m and cur is not None:
            flush()
            var, buf = m.group(1), [m.group(2)]
            continue
        if not line.strip():
            flush()
            var = None
            buf = []
            if states and cur is not None and len(cur) > 0 and not line.strip():
                pass
            continue
        if var is not None:
            buf.append(line.strip())
        elif states and (line.startswith('Finished') or re.search(r'states generated', line)):
            break
    flush()
    return states


# ---------------------------------------------------------------- chart
def contains(args, msg):
    for a in args:
        if a == msg or (isinstance(a, tuple) and contains(a, msg)):
            return True
    return False


def fmt(v):
    if isinstance(v, str):
        return v
    if isinstance(v, bool):
        return 'TRUE' if v else 'FALSE'
    if isinstance(v, (set, frozenset)):
        return '{' + ','.join(sorted(fmt(x) for x in v)) + '}'
    if isinstance(v, tuple):
        return '<<' + ','.join(fmt(x) for x in v) + '>>'
    return str(v)


def skey(v):
    """A deterministic sort key for a parsed TLC value."""
    if isinstance(v, dict):
        return '[' + ','.join('%s|->%s' % (k, skey(x)) for k, x in sorted(v.items())) + ']'
    if isinstance(v, (set, frozenset)):
        return '{' + ','.join(sorted(skey(x) for x in v)) + '}'
    if isinstance(v, tuple):
        return '<<' + ','.join(skey(x) for x in v) + '>>'
    return fmt(v)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('trace')
    ap.add_argument('out')
    ap.add_argument('--net', default='net')
    ap.add_argument('--action', default='lastAction')
    ap.add_argument('--lifelines', default='phase')
    ap.add_argument('--src', default='src')
    ap.add_argument('--dst', default='dst')
    ap.add_argument('--label', default='', help='comma-separated message fields to print on arrows')
    ap.add_argument('--names', default='', help='node=Name,... display names')
    ap.add_argument('--title', default='')
    a = ap.parse_args()

    with open(a.trace, encoding='utf-8', errors='replace') as f:
        states = parse_trace(f.read())
    if not states:
        sys.exit('seqchart: no error trace found in %s' % a.trace)
    names = dict(kv.split('=', 1) for kv in a.names.split(',') if kv)
    lanes = sorted(states[0][a.lifelines].keys(), key=lambda k: (str(type(k)), k))
    x_of = {n: 140 + 170 * i for i, n in enumerate(lanes)}
    label_fields = [x for x in a.label.split(',') if x]

    def nm(n):
        return names.get(str(n), str(n))

    row_h, top = 34, 90
    y_of = lambda k: top + row_h * k
    arrows = []     # (msg, step_sent, step_end, dst, kind)
    boxes = []      # (step, node, text)
    notes = []      # (step, text)
    open_msgs = {}  # msg -> step sent
    for k, st in enumerate(states):
        act = st.get(a.action, ('?',))
        act = act if isinstance(act, tuple) else (act,)
        notes.append((k, ' '.join(fmt(x) for x in act)))
        net = st.get(a.net, frozenset())
        prev = states[k - 1].get(a.net, frozenset()) if k else frozenset()
        # Sorted: set order depends on Python's per-process string hashing, and the
        # chart must be byte-identical from run to run (tools/spec.py diagram --check).
        for m in sorted(net - prev, key=skey):
            open_msgs.setdefault(m, k)
        name = str(act[0])
        for m in list(open_msgs):
            gone = m not in net
            if contains(act[1:], m) or (gone and not name.startswith(('Lose', 'Drop'))):
                arrows.append((m, open_msgs.pop(m), k, 'ok'))
            elif gone:
                arrows.append((m, open_msgs.pop(m), k, 'lost'))
        if k == 0:
            for n in lanes:
                boxes.append((0, n, fmt(st[a.lifelines][n])))
        else:
            for n in lanes:
                if st[a.lifelines][n] != states[k - 1][a.lifelines][n]:
                    boxes.append((k, n, fmt(st[a.lifelines][n])))
    last = len(states)
    for m, k0 in open_msgs.items():
        arrows.append((m, k0, last, 'flight'))

    width = 140 + 170 * (len(lanes) - 1) + 420
    height = y_of(last) + 40
    out = []
    w = out.append
    w('<svg xmlns="http://www.w3.org/2000/svg" width="%d" height="%d" font-family="monospace" font-size="11">'
      % (width, height))
    w('<defs><marker id="ah" markerWidth="8" markerHeight="8" refX="7" refY="3" orient="auto">'
      '<path d="M0,0 L7,3 L0,6 z" fill="#222"/></marker></defs>')
    w('<rect width="100%" height="100%" fill="white"/>')
    if a.title:
        w('<text x="10" y="20" font-size="13" font-weight="bold">%s</text>' % html.escape(a.title))
    for n in lanes:
        x = x_of[n]
        w('<rect x="%d" y="32" width="100" height="22" fill="#e8eef8" stroke="#335"/>' % (x - 50))
        w('<text x="%d" y="47" text-anchor="middle" font-weight="bold">%s</text>' % (x, html.escape(nm(n))))
        w('<line x1="%d" y1="54" x2="%d" y2="%d" stroke="#888" stroke-dasharray="4,3"/>' % (x, x, height - 20))
    notes_x = 140 + 170 * (len(lanes) - 1) + 90
    for k, text in notes:
        w('<text x="%d" y="%d" fill="#555">%d: %s</text>' % (notes_x, y_of(k) + 4, k + 1, html.escape(text)))
        w('<line x1="20" y1="%d" x2="%d" y2="%d" stroke="#f0f0f0"/>' % (y_of(k) + 8, notes_x - 10, y_of(k) + 8))
    for m, k0, k1, kind in arrows:
        src = m[a.src]
        dsts = [m[a.dst]] if m[a.dst] in x_of else [d for d in lanes if d != src]
        lab = ' '.join('%s=%s' % (f, fmt(m[f])) for f in label_fields if f in m)
        for d in dsts:
            if src not in x_of or d not in x_of:
                continue
            x0, y0, x1 = x_of[src], y_of(k0), x_of[d]
            y1 = y_of(k1) if kind != 'flight' else height - 25
            if kind == 'lost':
                xm, ym = x0 + (x1 - x0) * 0.8, y1
                w('<line x1="%d" y1="%d" x2="%d" y2="%d" stroke="#c22" stroke-width="1.5"/>' % (x0, y0, xm, ym))
                w('<text x="%d" y="%d" fill="#c22" font-size="16" text-anchor="middle">&#x2717;</text>'
                  % (xm, ym + 5))
                w('<text x="%d" y="%d" fill="#c22" font-size="10">lost (to %s)</text>'
                  % (xm + 8, ym + 4, html.escape(nm(d))))
            else:
                dash = ' stroke-dasharray="6,3"' if kind == 'flight' else ''
                w('<line x1="%d" y1="%d" x2="%d" y2="%d" stroke="#222" stroke-width="1.2"%s '
                  'marker-end="url(#ah)"/>' % (x0, y0, x1, y1, dash))
            if lab:
                tx = x0 + (x1 - x0) * 0.3
                ty = y0 + (y1 - y0) * 0.3 - 3
                w('<text x="%d" y="%d" fill="#125" font-size="10" text-anchor="middle">%s</text>'
                  % (tx, ty, html.escape(lab)))
    for k, n, text in boxes:
        x, y = x_of[n], y_of(k)
        hot = 'master' in text.lower() and 'follower' not in text.lower()
        w('<rect x="%d" y="%d" width="96" height="16" rx="4" fill="%s" stroke="#333"/>'
          % (x - 48, y - 8, '#f6c6c6' if hot else '#fff7d0'))
        w('<text x="%d" y="%d" text-anchor="middle" font-size="10">%s</text>' % (x, y + 4, html.escape(text)))
    w('</svg>')
    with open(a.out, 'w', encoding='utf-8') as f:
        f.write('\n'.join(out) + '\n')


if __name__ == '__main__':
    main()
