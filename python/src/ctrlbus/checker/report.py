# SPDX-License-Identifier: MIT
"""A check run as people and CI systems read it: a text summary, JSON, and JUnit XML."""

from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ET
from typing import Any

from ctrlbus import __version__
from ctrlbus.checker.framework import CheckOptions, CheckResult, Report, Status
from ctrlbus.checker.probe import Evidence

__all__ = [
    "render_details",
    "render_evidence",
    "render_header",
    "render_json",
    "render_junit",
    "render_result_line",
    "render_summary",
    "render_text",
]

TEXT_HEX_LIMIT = 48  # bytes of one evidence line shown in the text summary
JSON_HEX_LIMIT = 4096  # bytes of one evidence line kept in JSON (the size is always given)
TEXT_EVIDENCE_LINES = 40  # evidence lines shown per failed / warned check (all in JSON and JUnit)
ARROWS = {"sent": ">>", "received": "<<", "note": "  "}
SPEC = "docs/protocol.md"
_XML_UNSAFE = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ud800-\udfff\ufffe\uffff]")


def _hex(data: bytes, limit: int) -> str:
    if len(data) <= limit:
        return data.hex(" ").upper()
    head = data[: limit - 4].hex(" ").upper()
    tail = data[-4:].hex(" ").upper()
    return f"{head} ... {tail} ({len(data)} bytes)"


def render_evidence(evidence: list[Evidence], *, limit: int | None = None) -> list[str]:
    """Transcript lines: time since the check started, direction, bytes (hex), remark."""
    lines = []
    shown = evidence if limit is None or len(evidence) <= limit else evidence[:limit]
    for line in shown:
        stamp = f"{line.t_s * 1000:9.1f} ms"
        if line.direction == "note":
            lines.append(f"{stamp}     {line.note}")
        else:
            remark = f"   ({line.note})" if line.note else ""
            lines.append(f"{stamp}  {ARROWS[line.direction]} {_hex(line.data, TEXT_HEX_LIMIT)}{remark}")
    if limit is not None and len(evidence) > limit:
        lines.append(f"{'':12}     ... {len(evidence) - limit} more lines (see --json)")
    return lines


def _rules_text(result: CheckResult) -> str:
    return ", ".join(str(rule) for rule in result.check.rules)


def render_result_line(result: CheckResult) -> str:
    """One line: number, status, name, message."""
    check = result.check
    return f"{check.number:3d} {result.status.value.upper():4}  {check.name:20} {result.message}"


def render_header(port: str, options: CheckOptions) -> str:
    return (
        f"ctrlbus check {port}: profile {options.profile}, request timeout "
        f"{options.timeout_s * 1000:.0f} ms, answers awaited up to {options.wait_s * 1000:.0f} ms"
    )


def render_details(report: Report, *, verbose: bool = False) -> list[str]:
    """Findings and evidence of every failed or warned check (of every check with `verbose`)."""
    lines: list[str] = []
    for result in report.results:
        if not verbose and result.status not in (Status.FAIL, Status.WARN):
            continue
        check = result.check
        lines += [
            "",
            f"--- {check.number} {check.name}: {result.status.value.upper()} ({_rules_text(result)})",
        ]
        lines.append(f"    {check.title}")
        for finding in result.findings:
            if verbose or finding.status is not Status.PASS:
                lines.append(f"    {finding.status.value.upper()}: {finding.text}")
        lines.append("    evidence:")
        lines += ["    " + line for line in render_evidence(result.evidence, limit=TEXT_EVIDENCE_LINES)]
    return lines


def render_summary(report: Report) -> str:
    counts = report.counts()
    return (
        f"{counts[Status.PASS]} passed, {counts[Status.WARN]} warnings, {counts[Status.FAIL]} failed, "
        f"{counts[Status.SKIP]} skipped in {report.duration_s:.1f} s: "
        + ("FAIL" if report.failed else "PASS")
    )


def render_text(report: Report, *, verbose: bool = False) -> str:
    """The readable summary: a line per check, the details of every failure and warning (of every
    check with `verbose`), then the totals."""
    lines = [render_header(report.port, report.options), ""]
    lines += [render_result_line(result) for result in report.results]
    lines += render_details(report, verbose=verbose)
    lines += ["", render_summary(report)]
    return "\n".join(lines) + "\n"


def _evidence_json(evidence: list[Evidence]) -> list[dict[str, Any]]:
    items = []
    for line in evidence:
        item: dict[str, Any] = {"t_ms": round(line.t_s * 1000, 3), "direction": line.direction}
        if line.direction != "note":
            item["size"] = len(line.data)
            item["hex"] = line.data[:JSON_HEX_LIMIT].hex(" ").upper()
            if len(line.data) > JSON_HEX_LIMIT:
                item["truncated"] = True
        if line.note:
            item["note"] = line.note
        items.append(item)
    return items


def render_json(report: Report) -> str:
    """The whole run as JSON (schema in docs/checker.md)."""
    options = report.options
    counts = report.counts()
    data = {
        "tool": "ctrlbus check",
        "version": __version__,
        "port": report.port,
        "profile": options.profile,
        "timeout_ms": round(options.timeout_s * 1000, 3),
        "started": report.started,
        "duration_s": round(report.duration_s, 3),
        "result": "fail" if report.failed else "pass",
        "summary": {status.value: counts[status] for status in Status},
        "checks": [
            {
                "number": result.check.number,
                "name": result.check.name,
                "title": result.check.title,
                "rules": [
                    {"section": rule.section, "anchor": rule.anchor, "link": f"{SPEC}#{rule.anchor}"}
                    for rule in result.check.rules
                ],
                "status": result.status.value,
                "message": result.message,
                "findings": [{"status": f.status.value, "text": f.text} for f in result.findings],
                "duration_ms": round(result.duration_s * 1000, 3),
                "evidence": _evidence_json(result.evidence),
            }
            for result in report.results
        ],
        "preamble": _evidence_json(report.preamble),
    }
    return json.dumps(data, indent=2) + "\n"


def _xml_text(text: str) -> str:
    return _XML_UNSAFE.sub("?", text)


def _details(result: CheckResult) -> str:
    lines = [f"rules: {_rules_text(result)}"]
    lines += [f"{f.status.value.upper()}: {f.text}" for f in result.findings]
    lines.append("evidence:")
    lines += render_evidence(result.evidence)
    return _xml_text("\n".join(lines))


def render_junit(report: Report) -> str:
    """JUnit XML: one testcase per check; fail -> <failure>, skip -> <skipped>, warn -> a pass
    whose <system-out> starts with WARN."""
    counts = report.counts()
    total = len(report.results)
    attributes = {
        "name": "ctrlbus check",
        "tests": str(total),
        "failures": str(counts[Status.FAIL]),
        "errors": "0",
        "skipped": str(counts[Status.SKIP]),
        "time": f"{report.duration_s:.3f}",
    }
    root = ET.Element("testsuites", attributes)
    # The common JUnit schema wants a timestamp without a UTC offset (it is UTC).
    timestamp = report.started.removesuffix("+00:00")
    suite = ET.SubElement(root, "testsuite", {**attributes, "timestamp": timestamp})
    properties = ET.SubElement(suite, "properties")
    for name, value in (
        ("port", report.port),
        ("profile", report.options.profile),
        ("timeout_ms", f"{report.options.timeout_s * 1000:g}"),
        ("ctrlbus_version", __version__),
    ):
        ET.SubElement(properties, "property", {"name": name, "value": _xml_text(value)})
    for result in report.results:
        check = result.check
        case = ET.SubElement(
            suite,
            "testcase",
            {
                "classname": "ctrlbus.check",
                "name": f"{check.number:02d} {check.name}",
                "time": f"{result.duration_s:.3f}",
            },
        )
        message = _xml_text(result.message)
        if result.status is Status.FAIL:
            failure = ET.SubElement(case, "failure", {"message": message, "type": "fail"})
            failure.text = _details(result)
        elif result.status is Status.SKIP:
            ET.SubElement(case, "skipped", {"message": message})
        else:
            out = ET.SubElement(case, "system-out")
            prefix = "WARN: " if result.status is Status.WARN else "PASS: "
            out.text = prefix + message + "\n" + _details(result)
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
