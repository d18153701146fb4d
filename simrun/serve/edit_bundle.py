"""The scripts of the dashboard's edit mode: three.js's TransformControls and ``edit_page.js``, as classic scripts.

The viewer bundle (:func:`simrun.record.replay_html.viewer_bundle`, three.js r180 from the ``nicegui``
distribution) has GLTFLoader and OrbitControls but no TransformControls (nicegui's module does not export it
and its build leaves it out). The move and rotate handles of edit mode are three.js's own TransformControls
of the same release, kept verbatim in ``simrun/serve/vendor/TransformControls.js`` (from the npm package
``three@0.180.0``, ``examples/jsm/controls/TransformControls.js``, MIT: ``vendor/three-LICENSE``), turned
into a classic script the way the viewer bundle is: its ``import {...} from 'three'`` becomes a read of
``globalThis.SimrunThree.THREE`` and its ``export {...}`` an assignment to ``SimrunThree.TransformControls``.
Nothing is fetched at page load; the same files give the same text, byte for byte.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

from simrun.errors import SimrunError
from simrun.record.replay_html import _script_safe

_HERE = Path(__file__).resolve().parent
#: The vendored module and its release (the viewer bundle's three.js is r180 too).
TRANSFORM_CONTROLS = _HERE / "vendor" / "TransformControls.js"
THREE_RELEASE = "0.180.0"
#: SHA-256 of the file as the npm package ``three@0.180.0`` ships it.
TRANSFORM_CONTROLS_SHA256 = "621fb8894c0f748c2be2a6ff8a6bdd72c18a22b24ddfe21d506514544df5c84e"
_IMPORT = re.compile(r"\Aimport\s*\{([^{}]*)\}\s*from\s*'three';")
_EXPORT = re.compile(r"\bexport\s*\{([^{}]*)\};?\s*\Z")
_NAME = re.compile(r"[A-Za-z_$][\w$]*")


def transform_controls_script() -> str:
    """TransformControls as a classic script, run after the viewer bundle: sets ``SimrunThree.TransformControls``.

    Raises:
        SimrunError: The vendored file is missing or changed (how to restore it).
    """
    try:
        data = TRANSFORM_CONTROLS.read_bytes()
    except OSError as exc:
        raise SimrunError(
            f"the dashboard's edit mode needs {TRANSFORM_CONTROLS} ({exc.strerror}); reinstall simrun"
        ) from None
    if hashlib.sha256(data).hexdigest() != TRANSFORM_CONTROLS_SHA256:
        raise SimrunError(
            f"{TRANSFORM_CONTROLS} is not three.js {THREE_RELEASE}'s TransformControls.js; restore it "
            f"(npm pack three@{THREE_RELEASE}: package/examples/jsm/controls/TransformControls.js)"
        )
    module = data.decode("utf-8")
    imported, exported = _IMPORT.search(module), _EXPORT.search(module)
    if imported is None or exported is None:  # pragma: no cover - the digest fixes the text
        raise SimrunError(f"{TRANSFORM_CONTROLS}: no import from 'three' or export clause")
    names = ", ".join(_NAME.findall(imported.group(1)))
    exports = _NAME.findall(exported.group(1))
    body = module[imported.end() : exported.start()].rstrip()
    assign = "".join(f"globalThis.SimrunThree.{name} = {name};\n" for name in exports)
    return _script_safe(
        f"/* TransformControls from three.js {THREE_RELEASE} (npm three, examples/jsm/controls), "
        "MIT, Copyright 2010-2025 three.js authors; as a classic script */\n"
        f'(function () {{\n"use strict";\nconst {{ {names} }} = globalThis.SimrunThree.THREE;\n'
        f"{body}\n{assign}}})();\n"
    )


def edit_page_script() -> str:
    """The dashboard's edit mode (``edit_page.js``) after TransformControls, as one classic script's text."""
    page = (_HERE / "edit_page.js").read_text(encoding="utf-8")
    return transform_controls_script() + _script_safe(page)
