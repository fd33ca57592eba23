# SPDX-License-Identifier: MIT
#
# sigrok protocol decoder for the SLAMWARE Control Bus, stacked on 'uart'.
#
# libsigrokdecode runs decoders in its own Python, where the ctrlbus package
# is not installed, so this file carries its own small copy of the facts it
# needs: frame layout and stream decoder rules (docs/protocol.md sections 3
# and 7), message names and layouts (sections 4 and 5) and the way
# `ctrlbus decode` writes fields. python/tests/test_sigrok.py runs it with
# sigrok-cli next to `ctrlbus decode` on the same recording and on every
# frame vector, so the two cannot drift apart unnoticed.

import sigrokdecode as srd

CORE, BASE = 0, 1  # who sends: the Core's requests, the base's answers
SIDE = ('core', 'base')

FLAG_STANDARD, FLAG_LONG = 0x10, 0x50
MAX_FRAME = 65539

# --- names -------------------------------------------------------------------

# Names, bit meanings and layouts: protocol.py, generated from protocol/ctrlbus.json.
from .protocol import (ANSWERS, BASE_CMD_SUBCOMMANDS as BASE_SUBCOMMANDS, BASE_TYPES,
                       CTRL_REQUESTS, OK_COUNTED_HEAD, OK_SIZES, EVENTS, EXTERNAL_COMMANDS, HEALTH_COMPONENTS,
                       HEALTH_FLAGS_BITS as HEALTH_BITS, HEALTH_LEVELS, HEALTH_SUBS,
                       MOTOR_STATUS_BITS as MOTION_BITS, MOTOR_TYPES,
                       POWER_STATUS_BITS as POWER_BITS, REQUEST_ARGS, RESPONSES, TOP_REQUESTS)

ERROR_MEANINGS = {
    0x0010: 'channel not synchronised', 0x0020: 'request too long',
    0x0040: 'checksum mismatch', 0x00C0: 'checksum mismatch, reference form',
    0x8000: 'not supported', 0x8001: 'format error', 0x8002: 'operation failed',
}
# ERROR codes below this answer bytes on the line (the receiver's state bits, the reference's
# combined codes such as 0x0090 included), not a request: they pair with nothing.
LINE_FAULT_LIMIT = 0x0100
# Unit suffixes of field names (after _q8 / _q16), longest first.
UNITS = (('_mm_s', 'mm/s'), ('_radps', 'rad/s'), ('_mps', 'm/s'), ('_percent', '%'),
         ('_deg', 'deg'), ('_mm', 'mm'), ('_ms', 'ms'))
FIXED = (('_q16', 16), ('_q8', 8))

class FormatError(Exception):
    '''The payload does not have the layout of its message.'''


class Unsupported(Exception):
    '''A message (or argument value) the protocol does not define.'''


# --- message layouts -----------------------------------------------------------


class Reader:
    '''Little-endian fields from a payload, front to back.'''

    def __init__(self, data, what):
        self.data, self.at, self.what = data, 0, what

    def need(self, *sizes):
        if len(self.data) not in sizes:
            raise FormatError('%s: %d payload bytes, expected %s' % (
                self.what, len(self.data), ' or '.join(str(s) for s in sizes)))

    def int(self, size, signed=False):
        value = int.from_bytes(self.data[self.at:self.at + size], 'little', signed=signed)
        self.at += size
        return value

    def text(self, size, nul_required=False):
        raw = self.data[self.at:self.at + size]
        self.at += size
        text, nul, _ = raw.partition(b'\0')
        if nul_required and not nul:
            raise FormatError('%s: text not NUL-terminated' % self.what)
        try:
            return text.decode('ascii')
        except UnicodeDecodeError:
            raise FormatError('%s: text is not ASCII' % self.what)

    def rest(self):
        value = self.data[self.at:]
        self.at = len(self.data)
        return value


def request_name(cmd, payload):
    '''The request's name from CMD, request code and sub-command, or None.'''
    if cmd != 0xF8:
        return TOP_REQUESTS.get(cmd)
    if not payload:
        return None
    if payload[0] == 0x90:
        return HEALTH_SUBS.get(payload[1]) if len(payload) > 1 else None
    return CTRL_REQUESTS.get(payload[0])


def request_fields(cmd, payload):
    '''[(field, value)] of a request; FormatError or Unsupported.'''
    name = request_name(cmd, payload)
    read = Reader(payload, name or 'request')
    if cmd == 0x00:
        return [('filler', bytes(payload))]
    if cmd == 0x01:
        return [('data', bytes(payload))]
    if cmd == 0xF9:
        read.need(1)
        if payload[0] not in BASE_SUBCOMMANDS:
            raise Unsupported('BASE_CMD sub-command 0x%02X' % payload[0])
        return [('subcommand', payload[0])]
    if cmd != 0xF8:
        raise Unsupported('request CMD 0x%02X' % cmd)
    if not payload:
        raise FormatError('CTRL_BUS without a request code')
    if payload[0] == 0x90:
        if len(payload) < 2:
            raise FormatError('HEALTH_MGMT without a sub-command')
        if name is None:
            raise Unsupported('HEALTH_MGMT sub-command 0x%02X' % payload[1])
    elif name is None:
        raise Unsupported('request code 0x%02X' % payload[0])
    read.at = 2 if payload[0] == 0x90 else 1
    fields = read_fields(read, REQUEST_ARGS[name], read.at)
    # values the request codec refuses (messages.py): another protocol version, another data type
    if name == 'CONNECT_BASE' and payload[1] != 1:
        raise Unsupported('protocol version %d' % payload[1])
    if name == 'GET_CHARGER_DATA' and payload[1] != 0:
        raise Unsupported('charger data type %d' % payload[1])
    return fields


def read_fields(read, specs, head=0, sizes=None):
    '''[(field, value)] of fields laid out as the description says (protocol.py), after `head`
    bytes; the payload's size checked first: one of `sizes`, else exactly the fields.'''
    fixed = sum(spec['size'] * spec.get('count', 1) for spec in specs if spec['type'] != 'position')
    fixed += sum(16 * spec['count'] for spec in specs if spec['type'] == 'position')
    read.need(*(sizes or (head + fixed,)))
    fields = []
    for spec in specs:
        name, kind, count = spec['name'], spec['type'], spec.get('count')
        if spec.get('optional') and read.at >= len(read.data):
            value = None
        elif kind == 'text':
            value = read.text(count, nul_required=spec.get('nul_in_field', False))
        elif kind == 'position':
            value = [position(read) for _ in range(count)]
        elif kind == 'bytes':  # a list of counted bytes (probes), else bytes (the blob)
            value = list(read.rest()) if 'count_field' in spec else bytes(read.rest())
        elif spec.get('truncatable'):
            value = read.int(min(spec['size'], len(read.data) - read.at))
        elif count is not None:
            value = [read.int(spec['size'], kind == 's32') for _ in range(count)]
        else:
            value = read.int(spec['size'], kind == 's32')
        if spec.get('max_is_format_error') and value > spec['max']:
            raise FormatError('%s: %s above %d' % (read.what, name, spec['max']))
        fields.append((name, value))
    return fields


def position(read):
    return [('x_mm_q8', read.int(4, True)), ('y_mm_q8', read.int(4, True)),
            ('z_mm_q8', read.int(4, True)), ('angle_deg_q8', read.int(4))]


def ok_fields(to, payload):
    '''[(field, value)] of an OK answer to the request named `to`.'''
    read = Reader(payload, to + ' answer')
    if to == 'POLL_BASE_CMD':
        read.need(0, 2)
        if not payload:
            return [('command', None), ('payload_size', 0), ('pad', 0)]
        command = None if payload[0] == 0xFF else payload[0]
        return [('command', command), ('payload_size', 2), ('pad', payload[1])]
    layout = ANSWERS.get(to)
    if layout is None:
        raise Unsupported('no OK answer is defined for %s' % to)
    if 'count_at' in layout:  # a bytes field as long as the count before it says
        if len(payload) < layout['min'] or len(payload) != layout['min'] + payload[layout['count_at']]:
            raise FormatError('%s answer: %d payload bytes' % (to, len(payload)))
        sizes = (len(payload),)
    elif 'max' in layout:
        sizes = tuple(range(layout['min'], layout['max'] + 1))
    elif 'min' in layout:
        sizes = (len(payload),)
    else:
        sizes = layout['sizes']
    fields = read_fields(read, layout['fields'], sizes=sizes)
    if 'size_field' in layout:
        fields.append((layout['size_field'], len(payload)))
    return fields


# Value sizes of the 0x21 configuration tree's fixed-size types (the reference's type table).
TREE_FIXED = {0x10: 1, 0x11: 2, 0x1A: 4, 0x20: 4, 0x31: 1, 0x60: 0, 0x61: 0}
TREE_MAX_DEPTH = 32


def is_config_tree(payload):
    '''Whether `payload` is one whole 0x21 configuration tree (an object, nothing after it).'''
    def value(pos, type_code, depth):
        if type_code in TREE_FIXED:
            end = pos + TREE_FIXED[type_code]
            if end > len(payload):
                raise FormatError('truncated')
            return end
        if type_code == 0x30:
            if pos >= len(payload) or pos + 1 + payload[pos] > len(payload):
                raise FormatError('truncated string')
            return pos + 1 + payload[pos]
        if type_code in (0x40, 0x50):
            if depth + 1 > TREE_MAX_DEPTH or pos >= len(payload):
                raise FormatError('too deep or truncated')
            count, pos = payload[pos], pos + 1
            entry = 2 if type_code == 0x50 else 1
            if count * entry > len(payload) - pos:
                raise FormatError('count too large')
            for _ in range(count):
                pos += entry - 1  # an object's key
                if pos >= len(payload):
                    raise FormatError('truncated')
                pos = value(pos + 1, payload[pos], depth + 1)
            return pos
        raise FormatError('unknown type 0x%02X' % type_code)
    try:
        return bool(payload) and payload[0] == 0x50 and value(1, 0x50, 0) == len(payload)
    except FormatError:
        return False


# Every request with an OK answer, in ctrlbus's order: a lone OK answer is read as the one request
# whose answer alone can be its payload (as `ctrlbus decode` guesses).
OK_ANSWERS = ('BASE_CMD', 'CONNECT_BASE', 'GET_BASE_CONF', 'GET_BASE_CONF_ADV', 'GET_BASE_STATUS',
              'GET_BASE_MOTOR_DATA', 'GET_BASE_SENSOR_DATA', 'GET_BASE_BUMPER_DATA',
              'GET_CHARGER_DATA', 'SET_BASE_MOTOR', 'SET_V_AND_GET_DEADRECKON', 'POLL_BASE_CMD',
              'POLL_BASE_ANS_CMD', 'SEND_EVENT', 'HEALTH_GET_HEALTH', 'HEALTH_GET_ERROR',
              'HEALTH_CLR_ERROR')


# Pairing by order, timing and size, as `ctrlbus decode` (ctrlbus.annotate): the requests waiting
# are the last PAIR_DEPTH ones, none older than PAIR_WINDOW_S; an answer goes to the newest one it
# fits, and that one and every older one stop waiting. OK payload sizes per request: OK_SIZES
# (protocol.py).
PAIR_DEPTH = 4
PAIR_WINDOW_S = 1.0


def ok_size_fits(name, payload):
    sizes = OK_SIZES.get(name or '')
    if sizes is None:
        return True
    if sizes == 'any':
        return True
    if sizes == 'counted':
        head = OK_COUNTED_HEAD[name]
        return len(payload) >= head and len(payload) == head + payload[head - 1]
    return len(payload) in sizes


def answer_fits(request, cmd, payload):
    '''Whether an answer (cmd, payload) can answer `request` = (name, cmd, raw, time).'''
    if cmd in (0x00, 0x01):
        return request[1] == cmd
    if cmd == 0x02:
        return request[1] not in (0x00, 0x01) and ok_size_fits(request[0], payload)
    return True


def guess_request(payload):
    found = []
    for name in OK_ANSWERS:
        if name == 'GET_BASE_CONF_ADV':
            if not is_config_tree(payload):
                continue
        else:
            try:
                ok_fields(name, payload)
            except (FormatError, Unsupported):
                continue
        found.append(name)
        if len(found) > 1:
            return None
    return found[0] if found else None


def answer_fields(to, cmd, payload):
    '''[(field, value)] of an answer; `to` is the request it answers (None: unknown).'''
    if cmd == 0x02:
        return ok_fields(to, payload)
    if cmd == 0x00:
        return [('filler', bytes(payload))]
    if cmd == 0x01:
        return [('data', bytes(payload))]
    if cmd == 0x03:
        Reader(payload, 'ERROR answer').need(2)
        return [('error_code', payload[0] | payload[1] << 8)]
    if cmd == 0xFF:
        Reader(payload, 'INVALID answer').need(0)
        return []
    raise Unsupported('response 0x%02X' % cmd)


# --- fields as text (as `ctrlbus decode` writes them) --------------------------------


def split_name(key):
    '''vx_mps_q16 -> ('vx', 'm/s', 16)'''
    bits = 0
    for suffix, frac in FIXED:
        if key.endswith(suffix):
            key, bits = key[:-len(suffix)], frac
            break
    for suffix, unit in UNITS:
        if key.endswith(suffix):
            return key[:-len(suffix)], unit, bits
    return key, '', bits


def number_text(key, value):
    name, unit, bits = split_name(key)
    scale = float(1 << bits)
    if isinstance(value, list):
        items = ['%.3f' % (v / scale) if bits else str(v) for v in value]
        body = '[' + ', '.join(items) + ']'
    else:
        body = '%.3f' % (value / scale) if bits else str(value)
    return '%s %s%s' % (name, body, ' ' + unit if unit else '')


def bits_text(value, bits, none):
    named = [text for bit, text in bits if value & bit]
    return '0x%02X (%s)' % (value, ', '.join(named) if named else none)


def named_code(value, names):
    name = names.get(value)
    return '0x%02X %s' % (value, name) if name else '0x%02X' % value


def value_text(context, key, value):
    '''One field's value as `ctrlbus decode` writes it; `context` is the message's name
    ('ERROR' for an ERROR answer, 'OK to X' for an OK answer to X, else the request name).'''
    if key == 'error_code' and context == 'ERROR':
        return '0x%04X (%s)' % (value, ERROR_MEANINGS.get(value, 'unknown code'))
    if key == 'error_code':
        level = HEALTH_LEVELS.get(value >> 24, 'level %d' % (value >> 24))
        part = (value >> 16) & 0xFF
        component = HEALTH_COMPONENTS.get(part, 'component %d' % part)
        return '0x%08X (%s, %s, type 0x%02X, index %d)' % (
            value, level, component, (value >> 8) & 0xFF, value & 0xFF)
    if key == 'flags' and context == 'OK to HEALTH_GET_HEALTH':
        return bits_text(value, HEALTH_BITS, 'all well')
    if key == 'firmware_version':
        return '0x%04X (%d.%d)' % (value, value >> 8, value & 0xFF)
    if key == 'serial':
        return ''.join('%08X' % word for word in value)
    if isinstance(value, str):
        return repr(value)
    if key in ('event', 'command', 'subcommand'):
        names = {'event': EVENTS, 'command': EXTERNAL_COMMANDS, 'subcommand': BASE_SUBCOMMANDS}
        return named_code(value, names[key])
    if key == 'power_status':
        return bits_text(value, POWER_BITS, 'on battery')
    if key == 'status':
        return bits_text(value, MOTION_BITS, 'ok')
    if key == 'bitmap':
        return '0x%08X' % value
    if key == 'base_type':
        return '%d (%s)' % (value, BASE_TYPES.get(value, 'unknown'))
    if key == 'motor_type':
        return '%d (%s)' % (value, MOTOR_TYPES.get(value, 'unknown'))
    if isinstance(value, bytes):
        shown = ' '.join('%02X' % b for b in value[:16]) + (' ...' if len(value) > 16 else '')
        runs = printable_runs(value)
        text = ('  text ' + ' '.join(quoted(run) for run in runs)) if runs else ''
        return '%d bytes%s%s' % (len(value), ': ' + shown if value else '', text)
    return str(value)


MIN_TEXT_RUN = 4  # printable ASCII shown beside the hex from this many characters on (as ctrlbus decode)


def printable_runs(data):
    runs, current = [], bytearray()
    for byte in list(data) + [0]:
        if 0x20 <= byte < 0x7F:
            current.append(byte)
            continue
        if len(current) >= MIN_TEXT_RUN:
            runs.append(current.decode('ascii'))
        current = bytearray()
    return runs


def quoted(run):
    # JSON's quoting of printable ASCII, as ctrlbus decode writes it.
    return '"' + run.replace('\\', '\\\\').replace('"', '\\"') + '"'


def position_text(position):
    return '(' + ', '.join(number_text(key, value) for key, value in position) + ')'


def fields_text(context, fields):
    values = dict(fields)
    parts = []
    for key, value in fields:
        if key in ('sensors', 'bumpers'):
            count = values['sensor_num' if key == 'sensors' else 'bumper_num']
            used = [position_text(item) for item in value[:count]]
            if any(v for item in value[count:] for _, v in item):
                used += [position_text(item) for item in value[count:]]
            parts.append('%s [%s]' % (key, ', '.join(used)))
            continue
        short, unit, bits = split_name(key)
        if value is None:
            parts.append('%s none' % (short if bits or unit else key))
        elif (bits or unit) and isinstance(value, (int, list)):
            parts.append(number_text(key, value))
        else:
            parts.append('%s %s' % (key, value_text(context, key, value)))
    return ', '.join(parts)


# --- the stream decoder (docs/protocol.md section 7) -------------------------------------


class Stream:
    '''One direction's bytes to frames and events, rules D1-D5. Bytes come in one at a time as
    (value, ss, es) with a time (any unit: the decoder passes sample numbers, and the timeout in
    samples); `feed` returns what they completed: ('frame', bytes) and ('event', kind, first,
    last, extra) with `bytes` a list of (value, ss, es). `idle` is told the time while the line
    is idle, so that the inter-byte timeout fires without a next byte.'''

    def __init__(self, max_frame, timeout):
        self.max_frame, self.timeout = max_frame, timeout
        self.pending = []  # the bytes from the scan position on
        self.offset = 0  # stream offset of pending[0]
        self.silent_end = 0  # bytes before this offset are in a failed candidate's span
        self.quiet = False  # an event was raised since the last frame
        self.last_time = None

    def feed(self, byte, time):
        out = self.idle(time)
        self.last_time = time
        self.pending.append(byte)
        self.scan(out, flush=False)
        return out

    def idle(self, time):
        '''The time is now `time`: a candidate older than the timeout fails (D5).'''
        out = []
        if self.pending and self.timeout and time is not None and self.last_time is not None \
                and time - self.last_time > self.timeout:
            self.scan(out, flush=True)
        return out

    def fail(self, out, kind, size, span, extra=None):
        '''The candidate at pending[0] failed: drop its flag, report it unless silent.'''
        if self.offset >= self.silent_end:
            self.quiet = True
            out.append(('event', kind, self.pending[0], self.pending[size - 1], extra))
        self.silent_end = max(self.silent_end, self.offset + span)
        self.drop(1)

    def drop(self, count):
        del self.pending[:count]
        self.offset += count

    def scan(self, out, flush):
        pending = self.pending
        while pending:
            flag = pending[0][0]
            if flag not in (FLAG_STANDARD, FLAG_LONG):  # D1
                if not self.quiet and self.offset >= self.silent_end:
                    self.quiet = True
                    out.append(('event', 'garbage', pending[0], pending[0], None))
                self.drop(1)
                continue
            header = 2 if flag == FLAG_STANDARD else 3
            if len(pending) < header:
                if flush:
                    self.fail(out, 'timeout', len(pending), len(pending))
                    continue
                return
            length = pending[1][0] | (pending[2][0] << 8 if header == 3 else 0)
            size = header + length + 1
            if size > self.max_frame:  # D2
                self.fail(out, 'oversize', header, header, size)
                continue
            if len(pending) < size:
                if flush:  # D5
                    self.fail(out, 'timeout', len(pending), len(pending))
                    continue
                return
            check = 0
            for value, _, _ in pending[:size - 1]:
                check ^= value
            found = pending[size - 1][0]
            if check != found:  # D3, D4
                self.fail(out, 'checksum_error', size, size, (check, found))
                continue
            if length == 0:
                if self.offset >= self.silent_end:
                    self.quiet = True
                    out.append(('event', 'empty_frame', pending[0], pending[size - 1], None))
                self.drop(size)
                continue
            out.append(('frame', pending[:size]))
            self.quiet = False
            self.drop(size)


# --- the decoder -------------------------------------------------------------------


class Decoder(srd.Decoder):
    api_version = 3
    id = 'ctrlbus'
    name = 'Control Bus'
    longname = 'SLAMWARE Control Bus'
    desc = 'SLAMWARE Core <-> robot base protocol (ctrlbus).'
    license = 'mit'
    inputs = ['uart']
    outputs = []
    tags = ['Embedded/industrial']
    options = (
        {'id': 'requests', 'desc': 'UART line with the Core\'s requests', 'default': 'rx',
            'values': ('rx', 'tx')},
        {'id': 'timeout_ms', 'desc': 'Inter-byte timeout (ms, 0 = off)', 'default': 10},
        {'id': 'max_frame', 'desc': 'Largest frame (bytes)', 'default': MAX_FRAME},
    )
    annotations = (
        ('core-part', 'Core: frame parts'),
        ('core-msg', 'Core: requests'),
        ('core-err', 'Core: errors'),
        ('base-part', 'Base: frame parts'),
        ('base-msg', 'Base: answers'),
        ('base-err', 'Base: errors'),
    )
    annotation_rows = (
        ('core-parts', 'Core frames', (0,)),
        ('core-msgs', 'Core requests', (1,)),
        ('core-errs', 'Core errors', (2,)),
        ('base-parts', 'Base frames', (3,)),
        ('base-msgs', 'Base answers', (4,)),
        ('base-errs', 'Base errors', (5,)),
    )

    def __init__(self):
        self.reset()

    def reset(self):
        self.samplerate = None
        self.streams = None
        self.waiting = []  # (name, cmd, raw, time) of the requests waiting for an answer, oldest first

    def metadata(self, key, value):
        if key == srd.SRD_CONF_SAMPLERATE:
            self.samplerate = value
            self.set_timeout()

    def start(self):
        self.out_ann = self.register(srd.OUTPUT_ANN)
        max_frame = int(self.options['max_frame'])
        self.streams = (Stream(max_frame, 0), Stream(max_frame, 0))
        self.set_timeout()
        self.request_line = 0 if self.options['requests'] == 'rx' else 1

    def set_timeout(self):
        '''Time is counted in sample numbers (exact, and what sigrok gives): the timeout in
        samples needs the sample rate; without one it stays off.'''
        if self.streams is None or not self.samplerate:
            return
        samples = float(self.options['timeout_ms']) * self.samplerate / 1000.0
        for stream in self.streams:
            stream.timeout = samples

    def put_ann(self, side, kind, ss, es, texts):
        self.put(ss, es, self.out_ann, [side * 3 + kind, texts])

    def decode(self, ss, es, data):
        ptype, rxtx, pdata = data
        side = CORE if rxtx == self.request_line else BASE
        if ptype == 'IDLE':
            # uart reports each frame time of idle line: the timeout fires on idle time, not
            # only when a next byte comes (which never happens at the end of a recording).
            items = self.streams[side].idle(es)
        elif ptype == 'DATA':
            items = self.streams[side].feed((pdata[0], ss, es), ss)
        else:
            return
        for item in items:
            if item[0] == 'frame':
                self.show_frame(side, item[1])
            else:
                self.show_event(side, *item[1:])

    def show_event(self, side, kind, first, last, extra):
        if kind == 'garbage':
            texts = ['garbage: 0x%02X discarded' % first[0], 'garbage', 'G']
        elif kind == 'checksum_error':
            expected, found = extra
            texts = ['checksum error: checksum 0x%02X, expected 0x%02X' % (found, expected),
                     'checksum error', 'C']
        elif kind == 'oversize':
            texts = ['oversize: a frame of %d bytes announced' % extra, 'oversize', 'O']
        elif kind == 'timeout':
            texts = ['timeout: a frame stopped arriving', 'timeout', 'T']
        else:
            texts = ['empty frame (LEN = 0, no CMD)', 'empty frame', 'E']
        self.put_ann(side, 2, first[1], last[2], texts)

    def show_parts(self, side, frame):
        header = 2 if frame[0][0] == FLAG_STANDARD else 3
        length = len(frame) - header - 1
        cmd = frame[header][0] if length else None
        names = TOP_REQUESTS if side == CORE else RESPONSES
        self.put_ann(side, 0, frame[0][1], frame[0][2],
                     ['flag 0x%02X (%s)' % (frame[0][0], 'standard' if header == 2 else 'long'),
                      'flag', 'F'])
        self.put_ann(side, 0, frame[1][1], frame[header - 1][2],
                     ['LEN %d' % length, 'LEN', 'L'])
        if cmd is not None:
            cmd_name = names.get(cmd, '0x%02X' % cmd)
            self.put_ann(side, 0, frame[header][1], frame[header][2],
                         ['CMD 0x%02X %s' % (cmd, cmd_name), 'CMD', 'C'])
        if length > 1:
            self.put_ann(side, 0, frame[header + 1][1], frame[-2][2],
                         ['payload %d bytes' % (length - 1), 'payload', 'P'])
        self.put_ann(side, 0, frame[-1][1], frame[-1][2],
                     ['checksum 0x%02X' % frame[-1][0], 'checksum', 'X'])

    def frame_time(self, frame):
        return frame[-1][1] / float(self.samplerate) if self.samplerate else None

    def show_frame(self, side, frame):
        self.show_parts(side, frame)
        header = 2 if frame[0][0] == FLAG_STANDARD else 3
        cmd = frame[header][0]
        payload = bytes(value for value, _, _ in frame[header + 1:-1])
        error = None
        fields = []
        if side == CORE:
            name = request_name(cmd, payload)
            label = name or ('CTRL_BUS 0x%02X' % payload[0] if cmd == 0xF8 and payload
                             else 'CTRL_BUS' if cmd == 0xF8 else '0x%02X' % cmd)
            context = name
            try:
                fields = request_fields(cmd, payload)
            except FormatError:
                error = 'format'
            except Unsupported:
                error = 'unsupported'
            raw = bytes(value for value, _, _ in frame)
            self.waiting = (self.waiting + [(name, cmd, raw, self.frame_time(frame))])[-PAIR_DEPTH:]
        else:
            name = RESPONSES.get(cmd)
            label = name or '0x%02X' % cmd
            line_fault = cmd == 0x03 and len(payload) == 2 and \
                (payload[0] | payload[1] << 8) < LINE_FAULT_LIMIT
            to = None
            now = self.frame_time(frame)
            if now is not None:
                self.waiting = [item for item in self.waiting
                                if item[3] is None or now - item[3] <= PAIR_WINDOW_S]
            if not line_fault:
                for index in range(len(self.waiting) - 1, -1, -1):
                    if answer_fits(self.waiting[index], cmd, payload):
                        to = self.waiting[index][0]
                        del self.waiting[:index + 1]
                        break
                if to is not None:
                    label += ' to ' + to
            context = 'OK to %s' % to if cmd == 0x02 else label.split(' ')[0]
            if cmd == 0x02 and to is None:
                error = 'unpaired'
                guess = guess_request(payload)
                if guess is not None:
                    # read by its size, as `ctrlbus decode` does, and said to be a guess
                    label += ' (a guess: to %s)' % guess
                    context = 'OK to %s' % guess
                    fields = answer_fields(guess, cmd, payload)
            else:
                try:
                    fields = answer_fields(to or 'SYNC', cmd, payload)
                except FormatError:
                    error = 'format'
                except Unsupported:
                    error = 'unsupported'
        text = fields_text(context, fields) if error is None or fields is not None else ''
        full = label + (': ' + text if text else '') + (' [%s]' % error if error else '')
        self.put_ann(side, 1, frame[0][1], frame[-1][2], [full, label, label.split(' ')[0]])
