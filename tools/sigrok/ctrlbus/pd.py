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

TOP_REQUESTS = {0x00: 'SYNC', 0x01: 'ECHO', 0xF8: 'CTRL_BUS', 0xF9: 'BASE_CMD'}
RESPONSES = {0x00: 'SYNC', 0x01: 'ECHO', 0x02: 'OK', 0x03: 'ERROR', 0xFF: 'INVALID'}
CTRL_REQUESTS = {
    0x10: 'CONNECT_BASE', 0x20: 'GET_BASE_CONF', 0x21: 'GET_BASE_CONF_ADV',
    0x30: 'GET_BASE_STATUS', 0x31: 'GET_BASE_MOTOR_DATA',
    0x32: 'GET_BASE_SENSOR_DATA', 0x33: 'GET_BASE_BUMPER_DATA',
    0x34: 'GET_CHARGER_DATA', 0x35: 'GET_AUXILIARY_ANCHOR',
    0x40: 'SET_BASE_MOTOR', 0x41: 'SET_V_AND_GET_DEADRECKON',
    0x50: 'POLL_BASE_CMD', 0x5F: 'POLL_BASE_ANS_CMD', 0x60: 'SEND_EVENT',
    0x90: 'HEALTH_MGMT',
}
HEALTH_SUBS = {0x01: 'HEALTH_GET_HEALTH', 0x02: 'HEALTH_GET_ERROR', 0x03: 'HEALTH_CLR_ERROR'}
BASE_SUBCOMMANDS = {0x01: 'ENTER_DFU', 0x02: 'REBOOT'}
EVENTS = {
    0x61: 'LIDAR_CONN_FAIL', 0x62: 'LIDAR_RAMPUP_FAIL', 0x63: 'SYSTEM_UP_OK',
    0x64: 'FIRMWARE_UPDATE', 0x65: 'CORE_DISCONNECT', 0x66: 'FIRMWARE_UPDATE_OK',
    0x80: 'START_SWEEP', 0x81: 'END_SWEEP', 0x82: 'START_VACUUM', 0x83: 'END_VACUUM',
}
EXTERNAL_COMMANDS = {
    0x51: 'GET_INFO', 0x52: 'RESET_WIFI', 0x53: 'FW_UPGRADING', 0x80: 'START_SWEEP',
    0x81: 'STOP_SWEEP', 0x82: 'SPOT_SWEEP', 0x90: 'GET_HEALTH', 0xA0: 'MOVE_FORWARD',
    0xA1: 'MOVE_BACKWARD', 0xA2: 'TURN_LEFT', 0xA3: 'TURN_RIGHT', 0xA4: 'GO_HOME',
    0xAF: 'CANCEL_ACTION', 0xB0: 'GET_AUXILIARY_ANCHOR',
}
ERROR_MEANINGS = {
    0x0010: 'channel not synchronised', 0x0020: 'request too long',
    0x0040: 'checksum mismatch', 0x00C0: 'checksum mismatch, reference form',
    0x8000: 'not supported', 0x8001: 'format error', 0x8002: 'operation failed',
}
# ERROR codes below this answer bytes on the line (the receiver's state bits, the reference's
# combined codes such as 0x0090 included), not a request: they pair with nothing.
LINE_FAULT_LIMIT = 0x0100
POWER_BITS = ((0x01, 'charging'), (0x02, 'DC connected'), (0x04, 'on the dock'))
MOTION_BITS = ((0x02, 'wheel stall'), (0x04, 'traction lost'))
HEALTH_BITS = ((0x01, 'warning'), (0x02, 'error'), (0x04, 'fatal'))
HEALTH_LEVELS = {1: 'warning', 2: 'error', 4: 'fatal'}
HEALTH_COMPONENTS = {0: 'user', 1: 'system', 2: 'power', 3: 'motion', 4: 'sensor'}
BASE_TYPES = {0: 'round', 1: 'square'}
MOTOR_TYPES = {0: 'two-wheel differential'}
# Unit suffixes of field names (after _q8 / _q16), longest first.
UNITS = (('_mm_s', 'mm/s'), ('_radps', 'rad/s'), ('_mps', 'm/s'), ('_percent', '%'),
         ('_deg', 'deg'), ('_mm', 'mm'), ('_ms', 'ms'))
FIXED = (('_q16', 16), ('_q8', 8))
NO_ARGUMENT = ('GET_BASE_CONF', 'GET_BASE_CONF_ADV', 'GET_BASE_STATUS', 'GET_BASE_MOTOR_DATA',
               'GET_BASE_SENSOR_DATA', 'GET_BASE_BUMPER_DATA', 'GET_AUXILIARY_ANCHOR',
               'POLL_BASE_CMD', 'POLL_BASE_ANS_CMD')
EMPTY_OK = ('SET_BASE_MOTOR', 'POLL_BASE_ANS_CMD', 'SEND_EVENT', 'HEALTH_CLR_ERROR', 'BASE_CMD')


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
    if name in NO_ARGUMENT or name == 'HEALTH_GET_HEALTH':
        read.need(read.at)
        return []
    if name == 'CONNECT_BASE':
        read.need(2)
        if payload[1] != 1:
            raise Unsupported('protocol version %d' % payload[1])
        return [('protocol_version', 1)]
    if name == 'GET_CHARGER_DATA':
        read.need(2)
        if payload[1] != 0:
            raise Unsupported('charger data type %d' % payload[1])
        return [('data_type', 0)]
    if name == 'SET_BASE_MOTOR':
        read.need(17)
        return [('speeds_mm_s', [read.int(4, True) for _ in range(4)])]
    if name == 'SET_V_AND_GET_DEADRECKON':
        read.need(13)
        return [(key, read.int(4, True)) for key in ('vx_mps_q16', 'vy_mps_q16', 'omega_radps_q16')]
    if name == 'SEND_EVENT':
        read.need(2)
        return [('event', payload[1])]
    if name == 'HEALTH_GET_ERROR':
        read.need(3)
        return [('index', payload[2])]
    read.need(6)  # HEALTH_CLR_ERROR
    return [('error_code', read.int(4))]


def position(read):
    return [('x_mm_q8', read.int(4, True)), ('y_mm_q8', read.int(4, True)),
            ('z_mm_q8', read.int(4, True)), ('angle_deg_q8', read.int(4))]


def ok_fields(to, payload):
    '''[(field, value)] of an OK answer to the request named `to`.'''
    read = Reader(payload, to + ' answer')
    if to in EMPTY_OK:
        read.need(0)
        return []
    if to == 'CONNECT_BASE':
        read.need(28, 39)
        fields = [('model', read.text(12)), ('firmware_version', read.int(2)),
                  ('hardware_version', read.int(2)), ('serial', [read.int(4) for _ in range(3)])]
        suffix = read.text(11) if len(payload) == 39 else None
        return fields + [('firmware_version_suffix', suffix)]
    if to == 'GET_BASE_CONF':
        read.need(264)
        fields = [('base_type', read.int(1)), ('base_radius_mm_q8', read.int(4)),
                  ('motor_type', read.int(1)), ('sensor_num', read.int(1))]
        fields.append(('sensors', [position(read) for _ in range(8)]))
        fields.append(('bumper_num', read.int(1)))
        fields.append(('bumpers', [position(read) for _ in range(8)]))
        if fields[3][1] > 8 or fields[5][1] > 8:
            raise FormatError('GET_BASE_CONF answer: more than 8 sensors or bumpers')
        return fields
    if to == 'GET_BASE_CONF_ADV':
        return [('blob', bytes(payload))]
    if to == 'GET_BASE_STATUS':
        read.need(2)
        return [('battery_percent', payload[0]), ('power_status', payload[1])]
    if to == 'GET_BASE_MOTOR_DATA':
        read.need(9)
        return [('left_distance_mm', read.int(4, True)), ('right_distance_mm', read.int(4, True)),
                ('status', read.int(1))]
    if to == 'GET_BASE_SENSOR_DATA':
        read.need(64)
        return [('distances_mm_q16', [read.int(4) for _ in range(16)])]
    if to == 'GET_BASE_BUMPER_DATA':
        read.need(1, 2, 3, 4)
        return [('bitmap', read.int(len(payload))), ('payload_size', len(payload))]
    if to == 'GET_CHARGER_DATA':
        if len(payload) < 2 or len(payload) != 2 + payload[1]:
            raise FormatError('GET_CHARGER_DATA answer: %d payload bytes' % len(payload))
        return [('beacon_count', payload[0]), ('probe_count', payload[1]),
                ('probes', list(payload[2:]))]
    if to == 'SET_V_AND_GET_DEADRECKON':
        read.need(13, 17)
        fields = [(key, read.int(4, True)) for key in ('dx_mm_q16', 'dy_mm_q16', 'dtheta_deg_q16')]
        fields.append(('status', read.int(1)))
        return fields + [('timestamp_ms', read.int(4) if len(payload) == 17 else None)]
    if to == 'POLL_BASE_CMD':
        read.need(0, 2)
        if not payload:
            return [('command', None), ('payload_size', 0), ('pad', 0)]
        command = None if payload[0] == 0xFF else payload[0]
        return [('command', command), ('payload_size', 2), ('pad', payload[1])]
    if to == 'HEALTH_GET_HEALTH':
        read.need(2)
        return [('flags', payload[0]), ('error_count', payload[1])]
    if to == 'HEALTH_GET_ERROR':
        read.need(36)
        return [('error_code', read.int(4)), ('message', read.text(32, nul_required=True))]
    raise Unsupported('no OK answer is defined for %s' % to)


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
# fits, and that one and every older one stop waiting. OK payload sizes per request:
PAIR_DEPTH = 4
PAIR_WINDOW_S = 1.0
OK_SIZES = {
    'CONNECT_BASE': (28, 39), 'GET_BASE_CONF': (264,), 'GET_BASE_CONF_ADV': 'blob',
    'GET_BASE_STATUS': (2,), 'GET_BASE_MOTOR_DATA': (9,), 'GET_BASE_SENSOR_DATA': (64,),
    'GET_BASE_BUMPER_DATA': (1, 2, 3, 4), 'GET_CHARGER_DATA': 'charger',
    'SET_V_AND_GET_DEADRECKON': (13, 17), 'POLL_BASE_CMD': (0, 2), 'HEALTH_GET_HEALTH': (2,),
    'HEALTH_GET_ERROR': (36,), 'SET_BASE_MOTOR': (0,), 'POLL_BASE_ANS_CMD': (0,), 'SEND_EVENT': (0,),
    'HEALTH_CLR_ERROR': (0,), 'BASE_CMD': (0,),
}


def ok_size_fits(name, payload):
    sizes = OK_SIZES.get(name or '')
    if sizes is None:
        return True
    if sizes == 'blob':
        return True
    if sizes == 'charger':
        return len(payload) >= 2 and len(payload) == 2 + payload[1]
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
