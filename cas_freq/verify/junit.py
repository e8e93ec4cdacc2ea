"""JUnit XML of verdicts, as CI systems display it: a testsuite per variant, a testcase per
requirement; a failed required requirement is a ``<failure>``, a failed advisory one is
reported in ``<system-out>`` of a passing testcase (CI shows it without failing the build)."""

import xml.etree.ElementTree as ET


def junit_xml(config_name, verdicts_by_variant):
    """JUnit XML text.

    Parameters
    ----------
    config_name : str
        Name of the config (the ``classname`` prefix).
    verdicts_by_variant : dict of str to list of Verdict
        Variant name -> its verdicts, in order.

    Returns
    -------
    str
        The XML document (UTF-8 declaration, deterministic: no timestamps or timings).
    """
    suites = ET.Element("testsuites", name=f"cas-freq verify {config_name}")
    total = failed = 0
    for variant, verdicts in verdicts_by_variant.items():
        failures = sum(verdict.status == "FAIL" for verdict in verdicts)
        suite = ET.SubElement(
            suites, "testsuite", name=f"{config_name}/{variant}", tests=str(len(verdicts)),
            failures=str(failures), errors="0", skipped="0",
        )
        for verdict in verdicts:
            case = ET.SubElement(
                suite, "testcase", name=f"{verdict.id}: {verdict.metric}",
                classname=f"{config_name}.{variant}",
            )
            text = f"{verdict.message}; severity {verdict.severity}"
            if verdict.source:
                text += f"; source: {verdict.source}"
            if verdict.status == "FAIL":
                failure = ET.SubElement(case, "failure", message=verdict.message, type="FAIL")
                failure.text = text
            else:
                out = ET.SubElement(case, "system-out")
                out.text = f"{verdict.status}: {text}"
        total += len(verdicts)
        failed += failures
    suites.set("tests", str(total))
    suites.set("failures", str(failed))
    ET.indent(suites)
    body = ET.tostring(suites, encoding="unicode")
    return f'<?xml version="1.0" encoding="UTF-8"?>\n{body}\n'
