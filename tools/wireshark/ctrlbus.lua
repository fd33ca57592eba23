-- SPDX-License-Identifier: MIT
-- ctrlbus.lua: Wireshark/tshark dissector for SLAMWARE Control Bus captures made by ctrlbus.
--
-- The capture format (docs/capture-format.md): pcap, link type DLT_USER0 (147); each record is one
-- chunk as read from one side: a direction byte (0 = Core to base, 1 = base to Core) followed by
-- the bytes. Records are not frames. This dissector runs each direction's bytes through the stream
-- decoder of vectors/README.md ("The stream decoder, precisely"), so it shows frames split across
-- records, several frames in one record, garbage bytes, checksum failures (expected vs found),
-- oversize candidates, inter-byte timeouts and LEN = 0 frames, with the same events and counters
-- as ctrlbus's own decoders.
--
-- Use:
--   tshark -X lua_script:tools/wireshark/ctrlbus.lua -r capture.pcap -V
--   wireshark -X lua_script:tools/wireshark/ctrlbus.lua capture.pcap
-- or copy it with ctrlbus_protocol.lua (its generated tables, loaded from this file's folder)
-- into Wireshark's personal Lua plugins folder (Help > About > Folders).
-- Preferences: ctrlbus.max_frame (default 65539) and ctrlbus.timeout_ms (default 0 = off), e.g.
-- `-o ctrlbus.timeout_ms:20`. The timeout is checked, as StreamDecoder.feed does, when the next
-- record of the same direction arrives.
--
-- Field names. Every message field is `ctrlbus.<name>` with exactly the contract's field name from
-- vectors/README.md (ctrlbus.vx_mps_q16, ctrlbus.battery_percent, ...); nested ones add the parent
-- (ctrlbus.sensors.x_mm_q8); list fields occur once per element, in order. A field whose contract
-- value is null (or empty bytes) is absent. The message itself: ctrlbus.msg.kind (request/answer),
-- ctrlbus.msg.name, ctrlbus.msg.to (the request an answer answers), ctrlbus.msg.request_in.
-- Decoder results: ctrlbus.stream.event (a raised event, contract name), ctrlbus.stream.silent and
-- .silent_count (failures inside an earlier failure's span, counted with no event: per kind, in the
-- run of silently dropped bytes they lie in), ctrlbus.stream.offset (offset in that direction's
-- byte stream), ctrlbus.counters.* (the direction's counters after the record).
--
-- Pairing answers with requests, by order, timing and size (as `ctrlbus decode`): the requests
-- waiting are the last PAIR_DEPTH request frames (Core to base), none older than PAIR_WINDOW_S. An
-- answer goes to the newest waiting request it fits (an OK of a size that request's answer can
-- have, a SYNC or ECHO to a request of the same CMD, any ERROR or INVALID); that request and every
-- older one stop waiting. An OK that fits none is unpaired. The line-fault codes (every ERROR
-- code below 0x0100: 0x0010, 0x0020, 0x0040, 0x00C0 and the reference's combined ones such as
-- 0x0090) answer bytes rather than a request: they get no `to` and leave the requests waiting.
--
-- Tested with tshark 4.0 (Lua 5.2). It needs neither a bit library nor Lua 5.3 operators, so that
-- builds on Lua 5.4 can run it too.

local P = Proto("ctrlbus", "SLAMWARE Control Bus")

-- The protocol's tables (names, bit meanings, fields, layouts), generated from
-- protocol/ctrlbus.json by `make generate` into ctrlbus_protocol.lua beside this file.
local PROTOCOL = dofile((debug.getinfo(1, "S").source:match("^@(.*[/\\])") or "") .. "ctrlbus_protocol.lua")

P.prefs.max_frame = Pref.uint("Largest frame (bytes)", 65539,
    "Candidates announcing a larger frame fail as oversize (header and checksum included)")
P.prefs.timeout_ms = Pref.uint("Inter-byte timeout (ms, 0 = off)", 0,
    "A partial frame older than this when the next chunk of its direction arrives fails as timeout")

---------------------------------------------------------------------------------------------------
-- Names

local DIRECTIONS = { [0] = "Core → base", [1] = "Base → Core" }
local FLAG_NAMES = { [0x10] = "standard", [0x50] = "long" }
local CMD_NAMES = PROTOCOL.CMD_NAMES
local REQUEST_NAMES = PROTOCOL.REQUEST_NAMES
local HEALTH_NAMES = PROTOCOL.HEALTH_NAMES
local BASE_CMD_NAMES = PROTOCOL.BASE_CMD_SUBCOMMANDS
local ERROR_NAMES = {
    [0x0010] = "channel not synchronised", [0x0020] = "request too long",
    [0x0040] = "checksum mismatch", [0x00C0] = "checksum mismatch (reference form)",
    [0x8000] = "not supported", [0x8001] = "format error", [0x8002] = "operation error",
}
-- ERROR codes that answer bytes on the line rather than a request.
-- ERROR codes below this are the receiver's state bits (protocol.md §11.6), not an answer to a request.
local LINE_FAULT_LIMIT = 0x0100
local LEVELS = PROTOCOL.HEALTH_LEVELS
local COMPONENTS = PROTOCOL.HEALTH_COMPONENTS

-- Binary configuration (0x21) dictionary, reference §5 (python/src/ctrlbus/binconf.py has the same).
local DICTIONARY = {
    [0x00] = "base", [0x01] = "manufacture_id", [0x02] = "manufacture_name", [0x03] = "model_id",
    [0x04] = "model_name", [0x05] = "hardware_version", [0x06] = "robot_size",
    [0x07] = "low_battery_percentage_for_charging", [0x08] = "high_battery_percentage_for_charging",
    [0x09] = "low_battery_auto_homing", [0x0A] = "sensors", [0x0B] = "type", [0x0C] = "bumper",
    [0x0D] = "installation_pose", [0x0E] = "x", [0x0F] = "y", [0x10] = "z", [0x11] = "yaw",
    [0x14] = "cliff", [0x15] = "sonar", [0x16] = "feature", [0x17] = "has_ir_docking_tower",
    [0x18] = "lidar", [0x19] = "id", [0x1A] = "motion_plan", [0x1B] = "bump_handle_strategy",
    [0x1C] = "default", [0x1E] = "side_margin", [0x1F] = "docking", [0x21] = "backward_docking",
    [0x22] = "docking_method", [0x23] = "landing_offset", [0x24] = "laserpattern",
    [0x26] = "head_up", [0x27] = "slamware_core_pose", [0x28] = "wheel_span",
    [0x29] = "reverse_installation", [0x2E] = "dock_center_line_length", [0x2F] = "hibernate_time",
    [0x30] = "dock_depth", [0x31] = "dock_inner_line_length", [0x32] = "dock_side_line_length",
    [0x3A] = "depth_camera", [0x3B] = "driver", [0x3C] = "max_distance", [0x3D] = "min_distance",
    [0x44] = "enable_use_filter", [0x45] = "enable_use_morphology_filter", [0x46] = "inversion",
    [0x47] = "min_filter_height", [0x48] = "max_filter_height",
}
local BINCONF_MAX_DEPTH = 32

---------------------------------------------------------------------------------------------------
-- Fields

local f = {
    direction = ProtoField.uint8("ctrlbus.direction", "Direction", base.DEC, DIRECTIONS),
    frame = ProtoField.none("ctrlbus.frame", "Frame"),
    flag = ProtoField.uint8("ctrlbus.frame.flag", "Flag", base.HEX, FLAG_NAMES),
    long = ProtoField.bool("ctrlbus.frame.long", "Long frame"),
    len = ProtoField.uint16("ctrlbus.frame.len", "LEN (CMD + payload)", base.DEC),
    cmd = ProtoField.uint8("ctrlbus.frame.cmd", "CMD", base.DEC_HEX, CMD_NAMES),
    payload = ProtoField.bytes("ctrlbus.frame.payload", "Payload"),
    checksum = ProtoField.uint8("ctrlbus.frame.checksum", "Checksum", base.HEX),
    first_packet = ProtoField.framenum("ctrlbus.frame.first_packet", "Frame starts in packet"),
    kind = ProtoField.string("ctrlbus.msg.kind", "Kind"),
    name = ProtoField.string("ctrlbus.msg.name", "Message"),
    to = ProtoField.string("ctrlbus.msg.to", "Answer to"),
    request_in = ProtoField.framenum("ctrlbus.msg.request_in", "Request in packet"),
    request_code = ProtoField.uint8("ctrlbus.msg.request_code", "Control-bus request", base.DEC_HEX, REQUEST_NAMES),
    health_sub = ProtoField.uint8("ctrlbus.msg.health_subcommand", "Health sub-command", base.DEC_HEX, HEALTH_NAMES),
    msg_error = ProtoField.string("ctrlbus.msg.error", "Message error"),
    event = ProtoField.string("ctrlbus.stream.event", "Decoder event"),
    silent = ProtoField.string("ctrlbus.stream.silent", "Silent failure"),
    silent_count = ProtoField.uint32("ctrlbus.stream.silent_count", "Silent failures of this kind", base.DEC),
    offset = ProtoField.uint32("ctrlbus.stream.offset", "Stream offset", base.DEC),
    discarded = ProtoField.bytes("ctrlbus.stream.discarded", "Discarded bytes"),
    expected = ProtoField.uint8("ctrlbus.stream.checksum_expected", "Checksum expected", base.HEX),
    found = ProtoField.uint8("ctrlbus.stream.checksum_found", "Checksum found", base.HEX),
    declared = ProtoField.uint32("ctrlbus.stream.declared_size", "Announced frame size", base.DEC),
    buffered = ProtoField.uint32("ctrlbus.stream.buffered", "Bytes of a partial frame waiting", base.DEC),
    binconf = ProtoField.none("ctrlbus.binconf", "Binary configuration"),
}

local COUNTER_NAMES = { "frames", "bytes_discarded", "checksum_errors", "oversize", "timeouts", "empty_frames", "resyncs" }
local counter_fields = {}
for _, name in ipairs(COUNTER_NAMES) do
    counter_fields[name] = ProtoField.uint32("ctrlbus.counters." .. name, name, base.DEC)
end

-- The contract's message fields: name -> ProtoField type, display base, value names (the
-- description's, and the SYNC / ECHO bytes).
local CONTRACT = { { "filler", "bytes" }, { "data", "bytes" } }
for _, spec in ipairs(PROTOCOL.FIELDS) do
    local names = spec[4] and PROTOCOL[spec[4]]
    CONTRACT[#CONTRACT + 1] = { spec[1], spec[2], spec[3] and base[spec[3]], names }
end
local cf = {}
for _, spec in ipairs(CONTRACT) do
    local name, ftype, display, names = spec[1], spec[2], spec[3], spec[4]
    local abbr = "ctrlbus." .. name
    if ftype == "bytes" or ftype == "string" then
        cf[name] = ProtoField[ftype](abbr, name)
    elseif ftype == "int32" then
        cf[name] = ProtoField.int32(abbr, name, base.DEC)
    else
        cf[name] = ProtoField[ftype](abbr, name, display, names)
    end
end

-- Units of the numeric contract fields: fixed-point shift and unit (by the last name part).
local UNITS = PROTOCOL.UNITS

local all_fields = {}
for _, field in pairs(f) do all_fields[#all_fields + 1] = field end
for _, field in pairs(counter_fields) do all_fields[#all_fields + 1] = field end
for _, field in pairs(cf) do all_fields[#all_fields + 1] = field end
P.fields = all_fields

local ex = {
    checksum = ProtoExpert.new("ctrlbus.expert.checksum", "Checksum error", expert.group.CHECKSUM, expert.severity.ERROR),
    garbage = ProtoExpert.new("ctrlbus.expert.garbage", "Garbage bytes", expert.group.PROTOCOL, expert.severity.WARN),
    oversize = ProtoExpert.new("ctrlbus.expert.oversize", "Oversize candidate", expert.group.MALFORMED, expert.severity.WARN),
    timeout = ProtoExpert.new("ctrlbus.expert.timeout", "Inter-byte timeout", expert.group.SEQUENCE, expert.severity.WARN),
    empty = ProtoExpert.new("ctrlbus.expert.empty_frame", "Empty frame (LEN = 0)", expert.group.MALFORMED, expert.severity.WARN),
    format = ProtoExpert.new("ctrlbus.expert.format", "Message format error", expert.group.MALFORMED, expert.severity.WARN),
    unsupported = ProtoExpert.new("ctrlbus.expert.unsupported", "Unsupported message", expert.group.PROTOCOL, expert.severity.NOTE),
    unpaired = ProtoExpert.new("ctrlbus.expert.unpaired", "Answer without a request", expert.group.SEQUENCE, expert.severity.NOTE),
    copy = ProtoExpert.new("ctrlbus.expert.copy", "Answer is not a copy of the request", expert.group.PROTOCOL, expert.severity.WARN),
    record = ProtoExpert.new("ctrlbus.expert.record", "Not a ctrlbus capture record", expert.group.MALFORMED, expert.severity.ERROR),
    binconf = ProtoExpert.new("ctrlbus.expert.binconf", "Bad binary configuration", expert.group.MALFORMED, expert.severity.WARN),
}
P.experts = { ex.checksum, ex.garbage, ex.oversize, ex.timeout, ex.empty, ex.format, ex.unsupported,
    ex.unpaired, ex.copy, ex.record, ex.binconf }

---------------------------------------------------------------------------------------------------
-- Small helpers (no bit library: Wireshark's Lua version varies)

local bxor = (bit32 and bit32.bxor) or (bit and bit.bxor) or function(a, b)
    local result, place = 0, 1
    while a > 0 or b > 0 do
        local abit, bbit = a % 2, b % 2
        if abit ~= bbit then result = result + place end
        a, b, place = (a - abit) / 2, (b - bbit) / 2, place * 2
    end
    return result
end

local function bit_set(value, bit_index)
    return math.floor(value / 2 ^ bit_index) % 2 == 1
end

local function hex2(value) return string.format("0x%02X", value) end

local function format_number(value)
    local text = string.format("%.6f", value):gsub("0+$", ""):gsub("%.$", "")
    return text
end

local function bits_text(value, names)
    local set = {}
    for bit_index = 0, 7 do
        if bit_set(value, bit_index) then set[#set + 1] = names[bit_index] or ("bit" .. bit_index) end
    end
    return #set > 0 and table.concat(set, ", ") or "none"
end

---------------------------------------------------------------------------------------------------
-- The stream decoder (vectors/README.md, "The stream decoder, precisely"), one per direction.
--
-- Bytes are taken one at a time, so what is "buffered" when a candidate fails is exactly what the
-- rules mean. The records whose bytes are still buffered are kept whole (`chunks`), so that results
-- can point into the packets they came from. Results are appended to `out` as items:
--   { type = "frame", data, offset, first_packet, first_offset, last_packet }
--   { type = "discarded", size, data (once finished), offset, packet, packet_offset, raised, silent,
--     failures (silent runs only: kind -> how many candidates failed inside the run) }
--   { type = "failure", kind, raised, size, offset, packet, packet_offset, expected, found, declared }
--   { type = "empty_frame", raised, data, size, offset, packet, packet_offset }
-- (all but frames are compact arrays, read by the same names: see compact_item below)
--
-- Cost: hostile input can make every third byte start a candidate of 65,539 bytes (`50 FF FF`
-- repeated), so nothing may cost a candidate's size per failure. Checksums come from a running
-- XOR of the stream (the XOR of a span is the XOR of two prefix values), a failure keeps the size
-- of its candidate instead of a copy of its bytes, failures inside an earlier failure's span
-- (silent: counted, no event) join the run of silently dropped bytes they lie in, and runs of
-- garbage are dropped in one step. So the work is O(1) per byte, and the memory kept per record is
-- its frames, its raised events and the bytes it dropped, never a candidate per failure.

-- Items other than frames can be as many as a third of the bytes (`10 00 FF` repeated raises a
-- checksum error every third byte), and every record's items are kept for later passes: they are
-- arrays (a Lua table with named fields costs about 700 bytes, an array of 10 about 220) read and
-- written by field name through these metatables.
local function compact_item(fields)
    return {
        __index = function(item, name)
            local index = fields[name]
            if index then return rawget(item, index) end
        end,
        __newindex = function(item, name, value) rawset(item, fields[name] or name, value) end,
    }
end
local DISCARDED = compact_item({ type = 1, offset = 2, size = 3, packet = 4, packet_offset = 5, raised = 6,
    silent = 7, data = 8, failures = 9 })
local FAILURE = compact_item({ type = 1, offset = 2, size = 3, packet = 4, packet_offset = 5, raised = 6,
    kind = 7, expected = 8, found = 9, declared = 10 })
local EMPTY_FRAME = compact_item({ type = 1, offset = 2, size = 3, packet = 4, packet_offset = 5, raised = 6,
    data = 7 })

local Decoder = {}
Decoder.__index = Decoder

local FLAG_PATTERN = "[\16\80]"  -- 0x10 or 0x50

function Decoder.new(max_frame, timeout_ms)
    local counters = {}
    for _, name in ipairs(COUNTER_NAMES) do counters[name] = 0 end
    return setmetatable({
        -- The buffered bytes: a ring of max_frame slots (no candidate is ever longer), the byte of
        -- stream offset i in slot i % max_frame + 1; head and tail are the stream offsets of the
        -- first and last byte buffered (tail = head - 1 when none is).
        bytes = {}, head = 0, tail = -1,
        prefix = {},           -- per slot: XOR of the stream's bytes up to that byte ...
        consumed_prefix = 0,   -- ... so the XOR of bytes head..i is prefix(i) XOR this
        chunks = {},           -- the records holding buffered bytes: { packet, start, data }
        first_chunk = 1,       -- the chunk holding bytes[head] (or the next byte)
        last_chunk = 0,
        stream_offset = 0,     -- stream offset of bytes[head]
        fed = 0,               -- bytes of this direction fed so far
        silent = 0,            -- how many bytes from head on lie in a failed candidate's span
        quiet = false,         -- an event was raised since the last yielded frame
        counters = counters,
        max_frame = math.max(max_frame, 5),
        timeout_ms = timeout_ms,
        last_time = nil,
        need = 1,              -- bytes that must be buffered before anything can be decided
        chunks_by_packet = {}, -- packet number -> chunk, for the items of the record being fed
    }, Decoder)
end

function Decoder:count() return self.tail - self.head + 1 end

-- The chunk holding stream offset `offset` (at or after head), and its index.
function Decoder:chunk_at(offset)
    local chunks, index = self.chunks, self.first_chunk
    while chunks[index].start + #chunks[index].data <= offset do index = index + 1 end
    return chunks[index], index
end

-- `count` bytes of the stream from `offset` on, from the chunks (no byte-by-byte copy).
function Decoder:stream_bytes(offset, count)
    local chunk, index = self:chunk_at(offset)
    local parts = {}
    while count > 0 do
        local from = offset - chunk.start + 1
        local take = math.min(count, #chunk.data - from + 1)
        parts[#parts + 1] = chunk.data:sub(from, from + take - 1)
        offset, count = offset + take, count - take
        index = index + 1
        chunk = self.chunks[index]
    end
    return table.concat(parts)
end

function Decoder:origin()
    local chunk = self:chunk_at(self.stream_offset)
    return chunk.packet, self.stream_offset - chunk.start
end

-- The buffered byte at stream offset `offset`.
function Decoder:byte_at(offset) return self.bytes[offset % self.max_frame + 1] end

-- XOR of `count` buffered bytes from head on.
function Decoder:xor_of(count)
    if count == 0 then return 0 end
    return bxor(self.prefix[(self.head + count - 1) % self.max_frame + 1], self.consumed_prefix)
end

function Decoder:consume(count)
    self.consumed_prefix = self.prefix[(self.head + count - 1) % self.max_frame + 1]
    self.head = self.head + count
    self:advance(count)
end

-- The stream moved on by `count` bytes (consumed, or dropped before they were buffered).
function Decoder:advance(count)
    self.stream_offset = self.stream_offset + count
    self.silent = math.max(0, self.silent - count)
    local chunks = self.chunks
    while chunks[self.first_chunk] and chunks[self.first_chunk].start + #chunks[self.first_chunk].data
        <= self.stream_offset do
        self.first_chunk = self.first_chunk + 1
    end
end

-- Forget the chunks whose bytes are all consumed (once the record's items are finished).
function Decoder:prune()
    for index = self.first_chunk - 1, 1, -1 do
        local chunk = self.chunks[index]
        if not chunk then break end
        self.chunks[index], self.chunks_by_packet[chunk.packet] = nil, nil
    end
end

-- Note `count` dropped bytes from the stream offset on (all from one chunk): joined to the run of
-- dropped bytes before them where they continue one (same packet, adjacent, the same silence, no
-- event of their own). `failed` names the kind of a silent failure whose flag byte is dropped;
-- `garbage` says whether the first byte may raise the garbage event. Returns the item.
function Decoder:note_drop(out, count, failed, garbage)
    local silent = self.silent > 0
    local raise = garbage and not silent and not self.quiet
    if raise then self.quiet = true end
    local packet, packet_offset = self:origin()
    local last = out[#out]
    local item
    if last and last.type == "discarded" and last.packet == packet and last.silent == silent
        and last.offset + last.size == self.stream_offset and not raise then
        item = last
        item.size = item.size + count
    else
        item = setmetatable({ "discarded", self.stream_offset, count, packet, packet_offset, raise, silent,
            false, false }, DISCARDED)
        out[#out + 1] = item
    end
    if failed then
        item.failures = item.failures or {}
        item.failures[failed] = (item.failures[failed] or 0) + 1
    end
    return item
end

-- How many bytes from the stream offset on can be dropped as one piece: not past `count`, the end
-- of the silent span (where the silence changes) or the end of the chunk.
function Decoder:piece(count)
    local chunk = self:chunk_at(self.stream_offset)
    local take = math.min(count, chunk.start + #chunk.data - self.stream_offset)
    if self.silent > 0 then take = math.min(take, self.silent) end
    return take
end

-- Drop the garbage bytes from head on up to the next flag byte buffered.
function Decoder:discard_garbage(out)
    local bytes, ring, stop = self.bytes, self.max_frame, self.head
    while stop <= self.tail do
        local byte = bytes[stop % ring + 1]
        if byte == 0x10 or byte == 0x50 then break end
        stop = stop + 1
    end
    local count = stop - self.head
    self.counters.bytes_discarded = self.counters.bytes_discarded + count
    while count > 0 do
        local take = self:piece(count)
        self:note_drop(out, take, nil, true)
        self:consume(take)
        count = count - take
    end
end

-- Drop garbage before it is buffered: bytes `from`..`to` of the chunk being fed (buffer empty).
function Decoder:skip_garbage(out, from, to)
    local count = to - from + 1
    self.counters.bytes_discarded = self.counters.bytes_discarded + count
    while count > 0 do
        local take = self:piece(count)
        self:note_drop(out, take, nil, true)
        self.head, self.tail = self.head + take, self.tail + take  -- still none buffered
        self:advance(take)
        count = count - take
    end
end

-- Give dropped-byte runs their bytes once a record is done.
function Decoder:finish_items(items)
    for _, item in ipairs(items) do
        if item.type == "discarded" then
            local data = self.chunks_by_packet[item.packet].data
            item.data = data:sub(item.packet_offset + 1, item.packet_offset + item.size)
        end
    end
end

local FAILURE_COUNTERS = { checksum_error = "checksum_errors", oversize = "oversize", timeout = "timeouts" }

function Decoder:fail(kind, out, candidate_size, expected, found, declared)
    local buffered = self:count()
    local raised = self.silent == 0
    local counters = self.counters
    counters[FAILURE_COUNTERS[kind]] = counters[FAILURE_COUNTERS[kind]] + 1
    counters.resyncs = counters.resyncs + 1
    counters.bytes_discarded = counters.bytes_discarded + 1
    local span = buffered - 1
    if raised then
        self.quiet = true
        local packet, packet_offset = self:origin()
        out[#out + 1] = setmetatable({ "failure", self.stream_offset, math.min(candidate_size, buffered), packet,
            packet_offset, true, kind, expected or false, found or false, declared or false }, FAILURE)
    else
        self:note_drop(out, 1, kind, false)
    end
    self:consume(1)
    self.silent = math.max(self.silent, span)
end

-- Decide what can be decided about the bytes buffered. With `flush` (the timeout struck),
-- incomplete candidates fail as timeouts instead of waiting (rule 5).
function Decoder:process(out, flush)
    while self.head <= self.tail do
        local head = self.head
        local available = self.tail - head + 1
        local flag = self:byte_at(head)
        if flag ~= 0x10 and flag ~= 0x50 then
            self:discard_garbage(out)
        else
            local header = flag == 0x10 and 2 or 3
            if available < header then
                if not flush then self.need = header return end
                self:fail("timeout", out, available)
            else
                local len = flag == 0x10 and self:byte_at(head + 1)
                    or (self:byte_at(head + 1) + 256 * self:byte_at(head + 2))
                local size = header + len + 1
                if size > self.max_frame then
                    self:fail("oversize", out, header, nil, nil, size)
                elseif available < size then
                    if not flush then self.need = size return end
                    self:fail("timeout", out, available)
                else
                    local sum = self:xor_of(size - 1)
                    local found = self:byte_at(head + size - 1)
                    if sum ~= found then
                        self:fail("checksum_error", out, size, sum, found)
                    elseif len == 0 then
                        local raised = self.silent == 0
                        if raised then self.quiet = true end
                        self.counters.empty_frames = self.counters.empty_frames + 1
                        self.counters.bytes_discarded = self.counters.bytes_discarded + size
                        local packet, packet_offset = self:origin()
                        out[#out + 1] = setmetatable({ "empty_frame", self.stream_offset, size, packet, packet_offset,
                            raised, self:stream_bytes(self.stream_offset, size) }, EMPTY_FRAME)
                        self:consume(size)
                    else
                        local packet, packet_offset = self:origin()
                        out[#out + 1] = { type = "frame", data = self:stream_bytes(self.stream_offset, size),
                            offset = self.stream_offset, first_packet = packet, first_offset = packet_offset,
                            last_packet = self:chunk_at(self.stream_offset + size - 1).packet }
                        self.counters.frames = self.counters.frames + 1
                        self.quiet = false
                        self:consume(size)
                    end
                end
            end
        end
    end
    self.need = 1
end

-- One record of this direction: the timeout first (time in seconds), then its bytes.
function Decoder:feed(data, time, packet, out)
    -- whole microseconds, so that float noise in the timestamps cannot decide a tie
    if self.timeout_ms > 0 and self.tail >= self.head and self.last_time
        and math.floor((time - self.last_time) * 1e6 + 0.5) > self.timeout_ms * 1000 then
        self:process(out, true)
    end
    if #data == 0 then return end
    self.last_time = time
    local chunk = { packet = packet, start = self.fed, data = data }
    self.last_chunk = self.last_chunk + 1
    self.chunks[self.last_chunk] = chunk
    self.chunks_by_packet[packet] = chunk
    self.fed = self.fed + #data
    local bytes, prefix, ring = self.bytes, self.prefix, self.max_frame
    local i = 1
    while i <= #data do
        if self.head > self.tail then
            -- nothing buffered: garbage up to the next flag byte is dropped without buffering it
            local flag_at = data:find(FLAG_PATTERN, i) or #data + 1
            if flag_at > i then
                self:skip_garbage(out, i, flag_at - 1)
                i = flag_at
            end
        end
        if i <= #data then
            local tail = self.tail
            local byte = data:byte(i)
            local running = tail >= self.head and prefix[tail % ring + 1] or self.consumed_prefix
            tail = tail + 1
            self.tail = tail
            bytes[tail % ring + 1], prefix[tail % ring + 1] = byte, bxor(running, byte)
            if tail - self.head + 1 >= self.need then self:process(out, false) end
            i = i + 1
        end
    end
end

---------------------------------------------------------------------------------------------------
-- What a frame is, without a tree: enough to pair answers with requests on the first pass.

local function frame_parts(data)
    local flag = data:byte(1)
    local header = flag == 0x10 and 2 or 3
    local len = flag == 0x10 and data:byte(2) or (data:byte(2) + 256 * data:byte(3))
    return header, len, data:byte(header + 1), data:sub(header + 2, header + len)
end

-- The contract name of a request frame, or nil and a description when it has none.
local function request_name(cmd, payload)
    if cmd == 0x00 or cmd == 0x01 or cmd == 0xF9 then return CMD_NAMES[cmd] end
    if cmd ~= 0xF8 then return nil, "unknown command " .. hex2(cmd) end
    if #payload == 0 then return nil, "CTRL_BUS without a request code" end
    local code = payload:byte(1)
    if code == 0x90 then
        if #payload < 2 then return nil, "HEALTH_MGMT without a sub-command" end
        local name = HEALTH_NAMES[payload:byte(2)]
        if name then return name end
        return nil, "unknown HEALTH_MGMT sub-command " .. hex2(payload:byte(2))
    end
    if REQUEST_NAMES[code] then return REQUEST_NAMES[code] end
    return nil, "unknown control-bus request " .. hex2(code)
end

---------------------------------------------------------------------------------------------------
-- Per-capture state, rebuilt whenever Wireshark (re)reads a file.

local state

local function reset_state()
    state = {
        decoders = { [0] = Decoder.new(P.prefs.max_frame, P.prefs.timeout_ms),
                     [1] = Decoder.new(P.prefs.max_frame, P.prefs.timeout_ms) },
        records = {},       -- packet number -> what the first pass found
        waiting = {},       -- { name, label, packet, data, cmd, time } of the requests waiting, oldest first
    }
end

function P.init() reset_state() end
reset_state()

local PAIR_DEPTH = 4
local PAIR_WINDOW_S = 1.0
-- OK payload sizes each request's answer may have (ctrlbus_protocol.lua, as ctrlbus.annotate's).
local OK_SIZES = PROTOCOL.OK_SIZES

local function ok_size_fits(name, payload)
    local sizes = name and OK_SIZES[name]
    if not sizes then return true end
    local n = #payload
    if sizes == "any" then return true end
    if sizes == "counted" then
        local head = PROTOCOL.OK_COUNTED_HEAD[name]
        return n >= head and n == head + payload:byte(head)
    end
    for _, size in ipairs(sizes) do
        if n == size then return true end
    end
    return false
end

local function answer_fits(request, cmd, payload)
    if cmd == 0x00 or cmd == 0x01 then return request.cmd == cmd end
    if cmd == 0x02 then
        return request.cmd ~= 0x00 and request.cmd ~= 0x01 and ok_size_fits(request.name, payload)
    end
    return true
end

local function pair_frames(direction, items, time)
    for _, item in ipairs(items) do
        if item.type == "frame" then
            local _, _, cmd, payload = frame_parts(item.data)
            if direction == 0 then
                local name, problem = request_name(cmd, payload)
                table.insert(state.waiting, { name = name, label = name or problem, packet = item.first_packet,
                    last_packet = item.last_packet, data = item.data, cmd = cmd, time = time })
                while #state.waiting > PAIR_DEPTH do table.remove(state.waiting, 1) end
            else
                local kept = {}
                for _, request in ipairs(state.waiting) do
                    if time - request.time <= PAIR_WINDOW_S then table.insert(kept, request) end
                end
                state.waiting = kept
                local stream_error = cmd == 0x03 and #payload == 2
                    and payload:byte(1) + 256 * payload:byte(2) < LINE_FAULT_LIMIT
                if not stream_error then
                    for index = #kept, 1, -1 do
                        local request = kept[index]
                        if answer_fits(request, cmd, payload) then
                            item.to, item.to_label, item.request_in = request.name, request.label, request.last_packet
                            item.request_data = request.data
                            for _ = 1, index do table.remove(state.waiting, 1) end
                            break
                        end
                    end
                end
                item.stream_error = stream_error
            end
        end
    end
end

local function first_pass(number, direction, data, time)
    local decoder = state.decoders[direction]
    local items = {}
    local start = decoder.fed
    decoder:feed(data, time, number, items)
    decoder:finish_items(items)
    decoder:prune()
    pair_frames(direction, items, time)
    local counters = {}
    for key, value in pairs(decoder.counters) do counters[key] = value end
    state.records[number] = { direction = direction, items = items, buffered = decoder:count(), counters = counters,
        start = start }
end

---------------------------------------------------------------------------------------------------
-- Message fields. Each function gets the tree, `at(offset, length)` giving a TvbRange of the
-- payload, and the payload length; it returns nil, or an error kind ("format" / "unsupported")
-- and its text.

local function add_number(tree, name, range, signed, value)
    local item
    if value ~= nil then
        item = tree:add(cf[name], range, value)
    else
        item = tree:add_le(cf[name], range)
        value = signed and range:le_int() or range:le_uint()
    end
    local unit = UNITS[name:match("[^.]+$")]
    if unit then
        if unit[1] > 0 then
            item:append_text(string.format(" (%s %s)", format_number(value / 2 ^ unit[1]), unit[2]))
        else
            item:append_text(" " .. unit[2])
        end
    end
    return value, item
end

local SIZES = { u8 = 1, u16 = 2, u32 = 4, s32 = 4 }

-- Fields laid out one after another: { name, kind[, count] }; returns the offset after them.
local function add_layout(tree, at, offset, layout)
    for _, spec in ipairs(layout) do
        local name, kind, count = spec[1], spec[2], spec[3] or 1
        for _ = 1, count do
            add_number(tree, name, at(offset, SIZES[kind]), kind == "s32")
            offset = offset + SIZES[kind]
        end
    end
    return offset
end

-- A NUL-padded ASCII text field; returns an error text when it is not one (as messages.py).
local function add_text(tree, name, range, nul_required)
    local raw = range:raw()
    local nul = raw:find("\0", 1, true)
    local text = nul and raw:sub(1, nul - 1) or raw
    if text:find("[\128-\255]") then return name .. " is not ASCII text" end
    if nul_required and not nul then return name .. " is not NUL-terminated" end
    tree:add(cf[name], range, text)
    return nil
end

local function add_position(tree, at, offset, list_name, index)
    local sub = tree:add(at(offset, 16), string.format("%s[%d]", list_name, index))
    add_layout(sub, at, offset, { { list_name .. ".x_mm_q8", "s32" }, { list_name .. ".y_mm_q8", "s32" },
        { list_name .. ".z_mm_q8", "s32" }, { list_name .. ".angle_deg_q8", "u32" } })
    return offset + 16
end

local function describe_error_code(value)
    local level = math.floor(value / 2 ^ 24) % 256
    local component = math.floor(value / 2 ^ 16) % 256
    return string.format("%s, %s, type 0x%02X, index %d", LEVELS[level] or ("level " .. level),
        COMPONENTS[component] or ("component " .. component), math.floor(value / 256) % 256, value % 256)
end

local function need(length, ...)
    for _, allowed in ipairs({ ... }) do
        if length == allowed then return nil end
    end
    local sizes = table.concat({ ... }, " or ")
    return "format", string.format("%d payload bytes, expected %s", length, sizes)
end

-- Binary configuration tree (0x21): shown entry by entry; returns nil or an error text.
local BINCONF_FIXED = { [0x10] = { 1, "u8" }, [0x11] = { 2, "u16" }, [0x1A] = { 4, "s32" }, [0x20] = { 4, "f32" } }

local function binconf_value(tree, at, size, offset, label, depth)
    if offset >= size then return nil, "truncated: a value type is missing", offset end
    local start = offset
    local type_code = at(offset, 1):uint()
    offset = offset + 1
    local fixed = BINCONF_FIXED[type_code]
    if fixed then
        if offset + fixed[1] > size then return nil, "truncated " .. fixed[2], start end
        local range = at(offset, fixed[1])
        local value
        if fixed[2] == "s32" then value = tostring(range:le_int())
        elseif fixed[2] == "f32" then value = string.format("%.7g", range:le_float())
        else value = tostring(range:le_uint()) end
        tree:add(at(start, 1 + fixed[1]), string.format("%s: %s (%s)", label, value, fixed[2]))
        return offset + fixed[1]
    elseif type_code == 0x30 then
        if offset >= size then return nil, "truncated string length", start end
        local length = at(offset, 1):uint()
        if offset + 1 + length > size then return nil, "truncated string", start end
        local text = length > 0 and at(offset + 1, length):raw() or ""
        tree:add(at(start, 2 + length), string.format("%s: %q (string)", label, text))
        return offset + 1 + length
    elseif type_code == 0x31 then
        if offset >= size then return nil, "truncated dictionary id", start end
        local ident = at(offset, 1):uint()
        tree:add(at(start, 2), string.format("%s: %s (dictionary id 0x%02x)", label,
            DICTIONARY[ident] or "unknown", ident))
        return offset + 1
    elseif type_code == 0x60 or type_code == 0x61 then
        tree:add(at(start, 1), string.format("%s: %s", label, type_code == 0x60 and "true" or "false"))
        return offset
    elseif type_code == 0x40 or type_code == 0x50 then
        if depth > BINCONF_MAX_DEPTH then return nil, "nesting deeper than " .. BINCONF_MAX_DEPTH, start end
        if offset >= size then return nil, "truncated count", start end
        local count = at(offset, 1):uint()
        offset = offset + 1
        local is_object = type_code == 0x50
        local sub = tree:add(at(start, 2), string.format("%s: %s of %d", label, is_object and "object" or "array", count))
        for index = 1, count do
            local entry_label = "[" .. (index - 1) .. "]"
            if is_object then
                if offset >= size then return nil, "truncated key", offset end
                local key = at(offset, 1):uint()
                entry_label = DICTIONARY[key] or string.format("0x%02x", key)
                offset = offset + 1
            end
            local after, problem, where = binconf_value(sub, at, size, offset, entry_label, depth + 1)
            if not after then return nil, problem, where end
            offset = after
        end
        sub:set_len(offset - start)
        return offset
    end
    return nil, string.format("unknown type code 0x%02x", type_code), start
end

local function add_binconf(tree, at, size)
    local sub = tree:add(f.binconf, at(0, size))
    if size == 0 then return "empty blob" end
    if at(0, 1):uint() ~= 0x50 then return "the root is not an object (type 0x50)" end
    local after, problem, where = binconf_value(sub, at, size, 0, "root", 1)
    if not after then return string.format("%s at offset %d", problem, where) end
    if after < size then return string.format("%d trailing bytes at offset %d", size - after, after) end
    return nil
end

-- What the generic walker adds to a number: its bits, what a health code says, the probe's name.
local PROBE_NAMES = { "left", "main", "right" }
local function annotate(item, spec, value, index)
    if spec.health_code then
        item:append_text(" (" .. describe_error_code(value) .. ")")
    elseif spec.bits == "charger_probe" then
        item:append_text(string.format(" (%s probe sees: %s)", PROBE_NAMES[index + 1] or ("probe " .. index),
            bits_text(value, PROTOCOL.BITS.charger_probe)))
    elseif spec.bits and PROTOCOL.BITS[spec.bits] then
        item:append_text(" (" .. bits_text(value, PROTOCOL.BITS[spec.bits]) .. ")")
    elseif spec.bits then
        item:append_text(" (active low: 0 = triggered)")
    end
end

-- An OK answer laid out by the description (ctrlbus_protocol.lua ANSWERS): its size checked, then
-- its fields in wire order; an optional tail field only when the payload holds it.
local function answer_by_layout(layout)
    return function(tree, at, n)
        if layout.count_field then
            if n < layout.min or n ~= layout.min + at(layout.min - 1, 1):uint() then
                return "format", string.format("%d payload bytes, expected %d + %s", n, layout.min - 1,
                    layout.count_field)
            end
        elseif layout.max then
            if n < layout.min or n > layout.max then
                return "format", string.format("%d payload bytes, expected %d to %d", n, layout.min, layout.max)
            end
        elseif layout.sizes then
            local kind, text = need(n, (table.unpack or unpack)(layout.sizes))
            if kind then return kind, text end
        end
        local offset = 0
        for _, spec in ipairs(layout.fields) do
            local name, kind, count = spec[1], spec[2], spec[3] or 1
            if offset >= n and spec.optional then break end
            if kind == "text" then
                local problem = add_text(tree, name, at(offset, count), spec.nul_required)
                if problem then return "format", problem end
                offset = offset + count
            elseif kind == "position" then
                for index = 0, count - 1 do offset = add_position(tree, at, offset, name, index) end
            elseif kind == "bytes" then
                for index = 0, n - offset - 1 do
                    local value, item = add_number(tree, name, at(offset + index, 1))
                    annotate(item, spec, value, index)
                end
                offset = n
            elseif spec.truncatable then -- the word's low bytes, as many as were sent
                local size = math.min(SIZES[kind], n - offset)
                local value = 0
                for index = size - 1, 0, -1 do value = value * 256 + at(offset + index, 1):uint() end
                local _, item = add_number(tree, name, at(offset, size), false, value)
                annotate(item, spec, value)
                offset = offset + size
            else
                for _ = 1, count do
                    local value, item = add_number(tree, name, at(offset, SIZES[kind]), kind == "s32")
                    annotate(item, spec, value)
                    offset = offset + SIZES[kind]
                end
            end
        end
        if layout.size_field then add_number(tree, layout.size_field, at(0, n), false, n) end
    end
end

local OK_FIELDS = {
    GET_BASE_CONF_ADV = function(tree, at, n)
        if n == 0 then return "format", "an empty blob" end
        tree:add(cf.blob, at(0, n))
        local problem = add_binconf(tree, at, n)
        if problem then return "binconf", problem end
    end,
    POLL_BASE_CMD = function(tree, at, n)
        local kind, text = need(n, 0, 2)
        if kind then return kind, text end
        if n == 0 then
            tree:add(cf.payload_size, 0)
            tree:add(cf.pad, 0)
            return
        end
        local command = at(0, 1):uint()
        if command == 0xFF then
            tree:add(at(0, 1), "command: none pending (0xFF form)")
        else
            add_number(tree, "command", at(0, 1))
        end
        add_number(tree, "payload_size", at(0, 2), false, 2)
        add_number(tree, "pad", at(1, 1))
    end,
}
for name, layout in pairs(PROTOCOL.ANSWERS) do
    OK_FIELDS[name] = OK_FIELDS[name] or answer_by_layout(layout)
end
for _, name in ipairs({ "SET_BASE_MOTOR", "POLL_BASE_ANS_CMD", "SEND_EVENT", "HEALTH_CLR_ERROR", "BASE_CMD" }) do
    OK_FIELDS[name] = function(_, _, n) return need(n, 0) end
end

-- Control-bus request arguments (after the request code, and after the sub-command for HEALTH).
local REQUEST_ARGS = PROTOCOL.REQUEST_ARGS

local function layout_size(layout)
    local size = 0
    for _, spec in ipairs(layout) do size = size + SIZES[spec[2]] * (spec[3] or 1) end
    return size
end

local function request_fields(tree, at, n, cmd)
    if cmd == 0x00 then
        if n > 0 then tree:add(cf.filler, at(0, n)) end
        return
    elseif cmd == 0x01 then
        if n > 0 then tree:add(cf.data, at(0, n)) end
        return
    elseif cmd == 0xF9 then
        local kind, text = need(n, 1)
        if kind then return kind, text end
        local sub = at(0, 1):uint()
        add_number(tree, "subcommand", at(0, 1))
        if not BASE_CMD_NAMES[sub] then return "unsupported", "unknown BASE_CMD sub-command " .. hex2(sub) end
        return
    elseif cmd ~= 0xF8 then
        return "unsupported", "unknown command " .. hex2(cmd)
    end
    if n == 0 then return "format", "CTRL_BUS without a request code" end
    local code = at(0, 1):uint()
    tree:add(f.request_code, at(0, 1))
    local name = REQUEST_NAMES[code]
    if not name then return "unsupported", "unknown control-bus request " .. hex2(code) end
    local args_offset = 1
    if code == 0x90 then
        if n < 2 then return "format", "HEALTH_MGMT without a sub-command" end
        tree:add(f.health_sub, at(1, 1))
        name = HEALTH_NAMES[at(1, 1):uint()]
        if not name then return "unsupported", "unknown HEALTH_MGMT sub-command " .. hex2(at(1, 1):uint()) end
        args_offset = 2
    end
    local layout = REQUEST_ARGS[name] or {}
    local expected = layout_size(layout)
    if n - args_offset ~= expected then
        return "format", string.format("%s takes %d argument bytes, got %d", name, expected, n - args_offset)
    end
    add_layout(tree, at, args_offset, layout)
    -- values the request codec refuses (messages.py): another protocol version, another data type
    if name == "CONNECT_BASE" and at(1, 1):uint() ~= 1 then
        return "unsupported", "unsupported CONNECT_BASE protocol version " .. at(1, 1):uint()
    elseif name == "GET_CHARGER_DATA" and at(1, 1):uint() ~= 0 then
        return "unsupported", "unsupported GET_CHARGER_DATA data type " .. hex2(at(1, 1):uint())
    end
end

local function answer_fields(tree, at, n, cmd, item)
    if cmd == 0x00 or cmd == 0x01 then
        if n > 0 then tree:add(cmd == 0x00 and cf.filler or cf.data, at(0, n)) end
        return
    elseif cmd == 0x03 then
        local kind, text = need(n, 2)
        if kind then return kind, text end
        local code, item = add_number(tree, "error_code", at(0, 2))
        item:append_text(" (" .. (ERROR_NAMES[code] or "unknown code") .. ")")
        return
    elseif cmd == 0xFF then
        return need(n, 0)
    elseif cmd ~= 0x02 then
        return "unsupported", "unknown answer command " .. hex2(cmd)
    end
    if not item.to then
        return "unsupported", "OK to " .. (item.to_label or "no known request") .. ": the payload cannot be read"
    end
    local decode = OK_FIELDS[item.to]
    if not decode then
        return "unsupported", "no OK answer is defined for " .. item.to
    end
    return decode(tree, at, n)
end

---------------------------------------------------------------------------------------------------
-- Showing what the first pass found

local function item_tvb(tvb, pinfo, first_packet, first_offset, last_packet, data, label)
    if first_packet == pinfo.number and last_packet == pinfo.number then
        return tvb(1 + first_offset, #data):tvb()
    end
    return ByteArray.new(data, true):tvb(label)
end

local function show_frame(tree, tvb, pinfo, direction, item, summaries)
    local data = item.data
    local label = string.format("Frame (packets %d-%d)", item.first_packet, item.last_packet)
    local ftvb = item_tvb(tvb, pinfo, item.first_packet, item.first_offset, item.last_packet, data, label)
    local header, len, cmd = frame_parts(data)
    local flag = data:byte(1)
    local n = len - 1
    local frame_tree = tree:add(f.frame, ftvb())
    frame_tree:add(f.flag, ftvb(0, 1))
    frame_tree:add(f.long, ftvb(0, 1), flag == 0x50)
    frame_tree:add(f.len, ftvb(1, header - 1), len)
    frame_tree:add(f.cmd, ftvb(header, 1))
    if n > 0 then frame_tree:add(f.payload, ftvb(header + 1, n)) end
    frame_tree:add(f.checksum, ftvb(header + len, 1))
    frame_tree:add(f.offset, item.offset)
    if item.first_packet ~= pinfo.number then frame_tree:add(f.first_packet, item.first_packet) end

    local payload_start = header + 1
    local function at(offset, length) return ftvb(payload_start + offset, length) end
    local name, problem, kind, text
    if direction == 0 then
        name, problem = request_name(cmd, data:sub(header + 2, header + len))
        frame_tree:add(f.kind, "request")
        kind, text = request_fields(frame_tree, at, n, cmd)
    else
        name = CMD_NAMES[cmd] or hex2(cmd)
        frame_tree:add(f.kind, "answer")
        if item.to then
            frame_tree:add(f.to, item.to)
            frame_tree:add(f.request_in, item.request_in)
        elseif item.stream_error then
            frame_tree:add(ftvb(header, 1), "Answers bytes on the line, not a request")
        else
            frame_tree:add_proto_expert_info(ex.unpaired, "No outstanding request: " .. (item.to_label or "none waiting that it fits"))
        end
        kind, text = answer_fields(frame_tree, at, n, cmd, item)
        if (cmd == 0x00 or cmd == 0x01) and item.request_data and item.request_data ~= data then
            frame_tree:add_proto_expert_info(ex.copy)
        end
    end
    frame_tree:add(f.name, name or problem)
    local summary = name or problem
    if direction == 1 then
        if cmd == 0x03 and n == 2 then
            local code = ftvb(payload_start, 2):le_uint()
            summary = string.format("ERROR 0x%04X %s", code, ERROR_NAMES[code] or "")
        end
        if item.to_label then summary = summary .. " → " .. item.to_label end
    end
    if kind then
        frame_tree:add(f.msg_error, kind == "binconf" and "format" or kind):set_generated()
        local which = kind == "unsupported" and ex.unsupported or (kind == "binconf" and ex.binconf or ex.format)
        frame_tree:add_proto_expert_info(which, text)
        summary = summary .. " [" .. text .. "]"
    end
    frame_tree:append_text(string.format(": %s %s (%d bytes, %s)", direction == 0 and "request" or "answer",
        summary, #data, FLAG_NAMES[flag]))
    summaries[#summaries + 1] = summary
end

local function event_field(tree, item, kind)
    if item.raised then
        tree:add(f.event, kind)
    else
        tree:add(f.silent, kind):append_text(" (inside the span of an earlier failure: counted, no event)")
    end
end

-- The bytes of a failed candidate that lie in this record (a failure keeps no copy of its bytes:
-- see the stream decoder), or an empty range when they all came in earlier records.
local function candidate_range(tvb, record, item)
    local first = math.max(item.offset, record.start)
    local last = math.min(item.offset + item.size, record.start + tvb:len() - 1)
    if last <= first then return tvb(0, 0) end
    return tvb(1 + first - record.start, last - first)
end

local function silent_failures_text(failures)
    local parts = {}
    for _, kind in ipairs({ "checksum_error", "oversize", "timeout" }) do
        if failures[kind] then parts[#parts + 1] = string.format("%d %s", failures[kind], kind) end
    end
    return table.concat(parts, ", ")
end

local function show_failure(tree, tvb, pinfo, record, item, summaries)
    local whole = candidate_range(tvb, record, item)
    local sub
    if item.kind == "checksum_error" then
        local text = string.format("Checksum error: expected 0x%02X, found 0x%02X", item.expected, item.found)
        sub = tree:add(whole, text .. string.format(" (candidate of %d bytes)", item.size))
        sub:add(f.expected, item.expected)
        sub:add(f.found, item.found)
        sub:add_proto_expert_info(ex.checksum, text)
        summaries[#summaries + 1] = string.format("checksum error (0x%02X, expected 0x%02X)", item.found, item.expected)
    elseif item.kind == "oversize" then
        sub = tree:add(whole, string.format("Oversize candidate: announces %d bytes, more than %d", item.declared, P.prefs.max_frame))
        sub:add(f.declared, item.declared)
        sub:add_proto_expert_info(ex.oversize)
        summaries[#summaries + 1] = "oversize"
    else
        sub = tree:add(whole, string.format("Timeout: a partial frame of %d bytes was abandoned", item.size))
        sub:add_proto_expert_info(ex.timeout)
        summaries[#summaries + 1] = "timeout"
    end
    if item.packet ~= pinfo.number then
        sub:add(f.first_packet, item.packet):append_text(string.format(" (candidate starts at its byte %d)", item.packet_offset))
    end
    sub:add(f.offset, item.offset)
    event_field(sub, item, item.kind)
    sub:append_text("; its flag byte is dropped and the bytes after it are scanned again")
end

local function show_other(tree, tvb, pinfo, record, item, summaries)
    if item.type == "failure" then
        return show_failure(tree, tvb, pinfo, record, item, summaries)
    end
    local label = "Bytes from packet " .. item.packet
    local itvb = item_tvb(tvb, pinfo, item.packet, item.packet_offset, item.packet, item.data, label)
    local whole = itvb()
    if item.type == "discarded" then
        local sub = tree:add(f.discarded, whole)
        sub:prepend_text(string.format("%d garbage byte(s): ", item.size))
        sub:add(f.offset, item.offset)
        if item.raised then
            sub:add(f.event, "garbage")
            sub:add_proto_expert_info(ex.garbage, string.format("%d garbage byte(s) outside any frame", item.size))
            summaries[#summaries + 1] = "garbage"
        elseif item.silent then
            sub:append_text(" (inside the span of an earlier failure)")
        end
        if item.failures then
            -- flag bytes of candidates that failed inside the span: counted, no event
            sub:append_text(" (among them the flags of " .. silent_failures_text(item.failures) .. ")")
            for _, kind in ipairs({ "checksum_error", "oversize", "timeout" }) do
                if item.failures[kind] then
                    sub:add(f.silent, kind):append_text(string.format(" × %d (counted, no event)", item.failures[kind]))
                    sub:add(f.silent_count, item.failures[kind])
                end
            end
        end
        return
    end
    local sub = tree:add(whole, "Empty frame (LEN = 0): not a message")
    sub:add(f.offset, item.offset)
    event_field(sub, item, "empty_frame")
    if item.raised then
        sub:add_proto_expert_info(ex.empty)
        summaries[#summaries + 1] = "empty frame"
    end
end

function P.dissector(tvb, pinfo, tree)
    pinfo.cols.protocol = "CTRLBUS"
    local root = tree:add(P, tvb())
    if tvb:len() < 1 or tvb(0, 1):uint() > 1 then
        root:add_proto_expert_info(ex.record, "A record must start with a direction byte, 0 or 1")
        pinfo.cols.info = "not a ctrlbus capture record"
        return
    end
    local direction = tvb(0, 1):uint()
    pinfo.cols.src = direction == 0 and "Core" or "Base"
    pinfo.cols.dst = direction == 0 and "Base" or "Core"
    root:add(f.direction, tvb(0, 1))
    root:append_text(string.format(", %s, %d byte(s)", DIRECTIONS[direction], tvb:len() - 1))

    local record = state.records[pinfo.number]
    if not record then
        -- first pass (records are dissected in order); later passes reuse what it found
        local data = tvb:len() > 1 and tvb:raw(1, tvb:len() - 1) or ""
        first_pass(pinfo.number, direction, data, pinfo.abs_ts)
        record = state.records[pinfo.number]
    end

    local summaries = {}
    for _, item in ipairs(record.items) do
        if item.type == "frame" then
            show_frame(root, tvb, pinfo, direction, item, summaries)
        else
            show_other(root, tvb, pinfo, record, item, summaries)
        end
    end
    if record.buffered > 0 then
        root:add(f.buffered, record.buffered)
        if #summaries == 0 then summaries[1] = string.format("[%d byte(s) of a partial frame]", record.buffered) end
    end
    local counters = root:add(tvb(0, 0), "Decoder counters (" .. DIRECTIONS[direction] .. ", after this record)")
    for _, name in ipairs(COUNTER_NAMES) do counters:add(counter_fields[name], record.counters[name]) end

    pinfo.cols.info = #summaries > 0 and table.concat(summaries, "; ") or "(no frame)"
end

DissectorTable.get("wtap_encap"):add(wtap_encaps and wtap_encaps.USER0 or wtap.USER0, P)
