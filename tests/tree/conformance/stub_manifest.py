"""Turn `chaser-bt export-model` output into the harness's stub manifest (one node per line).

    python stub_manifest.py model.xml > manifest.txt

Each line is ``KIND ID port ... >output_port ...``; the harness registers every id that
BehaviorTree.CPP does not already provide as a stub leaf that returns SUCCESS.
"""

from __future__ import annotations

import sys
import xml.etree.ElementTree as ET


def manifest(model_xml: str) -> list[str]:
    lines = []
    for node in ET.fromstring(model_xml).iter():
        if node.tag not in ("Action", "Condition", "Decorator") or "ID" not in node.attrib:
            continue
        ports = [p.attrib["name"] for p in node if p.tag in ("input_port", "inout_port")]
        ports += [">" + p.attrib["name"] for p in node if p.tag == "output_port"]
        lines.append(" ".join([node.tag, node.attrib["ID"], *ports]))
    return lines


if __name__ == "__main__":
    with open(sys.argv[1], encoding="utf-8") as f:
        print("\n".join(manifest(f.read())))
