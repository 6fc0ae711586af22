"""The stewart MAVLink 2 dialect: generation, loading, and a pymavlink connection that speaks it.

Files
-----
``hil/message_definitions/stewart.xml``
    Our dialect; it includes ``common.xml``, which includes ``standard.xml``, which includes
    ``minimal.xml``. pymavlink's generator resolves ``<include>`` relative to the including file,
    so pinned copies of those three live beside ``stewart.xml`` (source and hashes in
    ``hil/message_definitions/README.md``).
``hil/mavlink_stewart.py``
    The Python module generated from it by pymavlink's own generator (``mavgen``, language
    ``Python3``, wire protocol 2.0, schema validation on). It is checked in and needs only the
    standard library at run time. ``tests/hil/test_dialect.py`` regenerates it and requires a
    byte-identical result. The generator writes no timestamp and no path (only the XML file
    *basenames* and the module name, which is why :func:`generate` always writes a file named
    ``mavlink_stewart.py``), so the output is reproducible for a given pymavlink version; a
    different pymavlink version may generate different code, hence the pin on
    :data:`GENERATOR_VERSION`.

After editing ``stewart.xml`` run ``python -m hil.dialect`` to regenerate the module.

Using the dialect with ``pymavlink.mavutil``
--------------------------------------------
``mavutil.set_dialect(name)`` (and so ``mavlink_connection(..., dialect=name)``) only imports
``pymavlink.dialects.v10/v20.<name>``, i.e. modules inside pymavlink's own package, and otherwise
tries to *generate* into pymavlink's install directory. We do neither. A ``mavutil.mavfile``
keeps its protocol object in ``self.mav`` (created in ``mavfile.__init__`` from the module-global
``mavutil.mavlink``); every send (``m.mav.<msg>_send``) and every receive path (``recv_msg``,
``recv_match``, which call ``self.mav.parse_char``) goes through ``self.mav``. So
:func:`connection` opens an ordinary mavutil connection and :func:`attach` replaces its ``mav``
with ``mavlink_stewart.MAVLink`` bound to the same mavfile (same source system/component,
robust parsing as mavutil set it), sets ``WIRE_PROTOCOL_VERSION = "2.0"`` and clears
``first_byte`` so mavutil's MAVLink 1 -> 2 auto-switch (``auto_mavlink_version``, which would
call ``set_dialect`` and rebuild ``mav`` from pymavlink's dialect) never runs. The module-global
``mavutil.mavlink`` is left alone (other code in the process may rely on it); mavutil uses it only
for enum constants that are identical in every dialect (``MAV_TYPE_*``, ``MAV_CMD_*``...).
Messages decoded by the connection are ``mavlink_stewart`` classes; build messages to send with
``m.mav.leg_setpoint_send(...)`` or ``m.mav.leg_setpoint_encode(...)``.
"""

from __future__ import annotations

import contextlib
import importlib.util
import io
import os
import shutil
import sys
import tempfile
from pathlib import Path
from types import ModuleType

HERE = Path(__file__).resolve().parent
XML_DIR = HERE / "message_definitions"
XML = XML_DIR / "stewart.xml"
MODULE_NAME = "mavlink_stewart"
MODULE_PATH = HERE / f"{MODULE_NAME}.py"

#: pymavlink version whose generator produced the checked-in module (and whose XML is pinned).
GENERATOR_VERSION = "2.4.50"
#: Our message ids start here (ids >= 44000 are unused by every dialect pymavlink ships).
FIRST_MSG_ID = 44000


def generate(output_dir: str | os.PathLike, xml: str | os.PathLike = XML, *, quiet: bool = True) -> Path:
    """Generate the Python module for ``xml`` into ``output_dir/mavlink_stewart.py``; return its path.

    The call is pymavlink's documented Python API::

        opts = mavgen.Opts(output=..., wire_protocol="2.0", language="Python3", validate=True)
        mavgen.mavgen(opts, [xml])

    ``validate=True`` checks every XML file against pymavlink's schema (needs lxml, a pymavlink
    dependency). mavgen prints progress on stdout; with ``quiet`` it is captured and only shown
    in the exception if generation fails.
    """
    from pymavlink.generator import mavgen, mavparse

    out = Path(output_dir) / f"{MODULE_NAME}.py"
    out.parent.mkdir(parents=True, exist_ok=True)
    opts = mavgen.Opts(output=str(out), wire_protocol=mavparse.PROTOCOL_2_0,
                       language="Python3", validate=True)
    log = io.StringIO()
    with contextlib.redirect_stdout(log) if quiet else contextlib.nullcontext():
        try:
            ok = mavgen.mavgen(opts, [str(Path(xml).resolve())])
        except SystemExit as exc:  # mavgen calls exit()/sys.exit() on some XML errors
            raise RuntimeError(f"mavgen failed ({exc}):\n{log.getvalue()}") from None
    if not ok or not out.is_file():
        raise RuntimeError(f"mavgen failed:\n{log.getvalue()}")
    return out


def regenerate(target: str | os.PathLike = MODULE_PATH) -> Path:
    """Regenerate the checked-in module (into a temp dir, then move it over ``target``)."""
    target = Path(target)
    with tempfile.TemporaryDirectory() as tmp:
        shutil.copyfile(generate(tmp), target)
    return target


def load(path: str | os.PathLike | None = None) -> ModuleType:
    """Return the dialect module, without ``mavutil.set_dialect()``.

    With no ``path``: the checked-in ``hil.mavlink_stewart`` (a normal import). With a path: that
    generated file, loaded under a private name (e.g. a fresh regeneration), not added to
    ``sys.modules``.
    """
    if path is None:
        from hil import mavlink_stewart
        return mavlink_stewart
    path = Path(path)
    spec = importlib.util.spec_from_file_location(f"_hil_dialect_{abs(hash(str(path)))}", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def attach(mf, dialect: ModuleType | None = None):
    """Make the mavutil connection ``mf`` speak our dialect (MAVLink 2); return ``mf``.

    Replaces ``mf.mav`` by the dialect's ``MAVLink`` bound to ``mf`` (keeping source ids, robust
    parsing and callbacks) and disables mavutil's protocol auto-switch.
    Call it before any traffic (a new ``mav`` starts with fresh sequence numbers and parser state,
    and without signing: set signing up afterwards with ``mf.setup_signing(...)``).
    """
    mod = dialect or load()
    old = mf.mav
    new = mod.MAVLink(mf, srcSystem=old.srcSystem, srcComponent=old.srcComponent)
    new.robust_parsing = getattr(mf, "robust_parsing", old.robust_parsing)
    for name in ("callback", "callback_args", "callback_kwargs",
                 "send_callback", "send_callback_args", "send_callback_kwargs"):
        setattr(new, name, getattr(old, name))
    mf.mav = new
    mf.WIRE_PROTOCOL_VERSION = mod.WIRE_PROTOCOL_VERSION
    mf.first_byte = False
    return mf


def connection(device: str, dialect: ModuleType | None = None, **kw):
    """Open a pymavlink connection that speaks the stewart dialect.

    ``device`` and ``kw`` are those of ``pymavlink.mavutil.mavlink_connection`` (e.g.
    ``"udpin:127.0.0.1:14550"``, ``"udpout:127.0.0.1:14550"``, a pseudo-terminal path with
    ``baud=...``, ``source_system=...``, ``source_component=...``), except ``dialect``, which here
    is a generated module (default: the checked-in ``hil.mavlink_stewart``), never a name.
    """
    from pymavlink import mavutil

    return attach(mavutil.mavlink_connection(device, **kw), dialect)


def main(argv: list[str] | None = None) -> int:
    """``python -m hil.dialect``: regenerate ``hil/mavlink_stewart.py`` from the XML."""
    import pymavlink

    if pymavlink.__version__ != GENERATOR_VERSION:
        print(f"warning: pymavlink {pymavlink.__version__} installed, the checked-in module is "
              f"pinned to {GENERATOR_VERSION}", file=sys.stderr)
    print(regenerate())
    return 0


if __name__ == "__main__":
    sys.exit(main())
