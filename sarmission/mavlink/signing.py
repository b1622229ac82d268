"""MAVLink 2 signing on the link: a timestamp counts only after its signature verifies.

pymavlink (2.4.50) ``check_signature`` stores a stream's timestamp *before* it compares the
signature, so one forged packet with timestamp 2^48-1 from the autopilot's (link id, system,
component) makes every later genuine packet "old": anyone can cut a signed link without the key.
:class:`SignatureCheck` replaces the check on one MAVLink object: it compares the signature first
and only then lets pymavlink judge (and store) the timestamp.

pymavlink's own accept/reject is bypassed (its allow-unsigned callback accepts everything) so that
every decoded message reaches the link with ``msg._signed`` (True only for a good signature with a
new timestamp) and :class:`SignatureGate` decides: verified -> accepted; no signature -> accepted
only with ``allow_unsigned``; bad signature -> never. Rejections are counted per sender and warned
about at most every :data:`WARN_S`; when autopilot-type senders are among them,
:meth:`SignatureGate.diagnosis` says in one line what is wrong with the signing setup.
"""

from __future__ import annotations

import hashlib
import hmac
import logging
from collections import Counter
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as M

from sarmission.mavlink.adoption import Source, is_autopilot_heartbeat

log = logging.getLogger(__name__)

#: Seconds between two warnings about rejected messages from one sender.
WARN_S = 5.0
UNSIGNED = "unsigned"
BAD_SIGNATURE = "bad signature"


class SignatureCheck:
    """Stands in for ``MAVLink.check_signature``: signature first, then pymavlink's timestamp
    rules. Counts, per (system, component) in the header, signatures that did not match
    (``mismatched``: another key, or forged) and good ones with an old timestamp (``stale``:
    replayed, or the sender's clock went back)."""

    def __init__(self, mav: Any) -> None:
        self._mav = mav
        self._timestamp_check = mav.check_signature
        self.mismatched: Counter[Source] = Counter()
        self.stale: Counter[Source] = Counter()

    @classmethod
    def install(cls, mav: Any) -> SignatureCheck:
        """Replace ``mav``'s signature check (signing must be set up); returns the check."""
        check = cls(mav)
        mav.check_signature = check
        return check

    def __call__(self, msgbuf: bytearray, src_system: int, src_component: int) -> bool:
        key = self._mav.signing.secret_key
        expected = hashlib.sha256(bytes(key) + bytes(msgbuf[:-6])).digest()[:6]
        if not hmac.compare_digest(expected, bytes(msgbuf[-6:])):
            self.mismatched[(src_system, src_component)] += 1
            return False
        if self._timestamp_check(msgbuf, src_system, src_component):
            return True
        self.stale[(src_system, src_component)] += 1
        return False


def enable_signing(conn: Any, key: bytes) -> SignatureCheck:
    """Sign what ``conn`` sends with ``key`` (32 bytes) and check what it receives with a
    :class:`SignatureCheck`; every decoded message is handed on, for a :class:`SignatureGate`."""
    if len(key) != 32:
        raise ValueError(f"signing key must be 32 bytes, got {len(key)}")
    conn.setup_signing(bytes(key), sign_outgoing=True, allow_unsigned_callback=_accept_all)
    return SignatureCheck.install(conn.mav)


def _accept_all(mav: Any, msg_id: int) -> bool:
    return True


def is_signed(msg: Any) -> bool:
    """Whether ``msg`` carried a signature block (good or bad)."""
    return bool(msg.get_header().incompat_flags & M.MAVLINK_IFLAG_SIGNED)


class SignatureGate:
    """Accepts or rejects each decoded message of a signed link (reader thread only)."""

    def __init__(self, check: SignatureCheck, allow_unsigned: bool = False) -> None:
        self.check = check
        self.allow_unsigned = allow_unsigned
        self.accepted_signed = 0
        self.accepted_unsigned = 0
        self.bad_signatures = 0
        self.unsigned_rejected = 0
        #: (sender, UNSIGNED or BAD_SIGNATURE) -> messages rejected.
        self.rejected: Counter[tuple[Source, str]] = Counter()
        #: (sender, kind) of rejected autopilot-type HEARTBEATs -> when the last one came.
        self.autopilot_rejected: dict[tuple[Source, str], float] = {}
        self._warned: dict[tuple[Source, str], float] = {}

    def admit(self, msg: Any, now: float) -> bool:
        """True when ``msg`` may be used: a verified signature, or none with ``allow_unsigned``."""
        if getattr(msg, "_signed", False):
            self.accepted_signed += 1
            return True
        signed = is_signed(msg)
        if not signed and self.allow_unsigned:
            self.accepted_unsigned += 1
            return True
        kind = BAD_SIGNATURE if signed else UNSIGNED
        if signed:
            self.bad_signatures += 1
        else:
            self.unsigned_rejected += 1
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        self.rejected[(src, kind)] += 1
        if is_autopilot_heartbeat(msg):
            self.autopilot_rejected[(src, kind)] = now
        last = self._warned.get((src, kind))
        if last is None or now - last >= WARN_S:
            self._warned[(src, kind)] = now
            log.warning(
                "rejected %d %s message(s) from %d/%d so far (signing is on)",
                self.rejected[(src, kind)],
                kind,
                *src,
            )
        return False

    def diagnosis(self, since: float) -> str | None:
        """One line naming what is wrong with signing, from autopilot-type senders rejected
        after ``since`` (``time.monotonic()``), or None when none was."""
        rejected = list(self.autopilot_rejected.items())  # the reader thread adds to it
        recent = [sk for sk, t in rejected if t > since]
        if not recent:
            return None
        src, kind = max(recent, key=lambda sk: self.rejected[sk])
        n = self.rejected[(src, kind)]
        if kind == UNSIGNED:
            return (
                f"autopilot {src[0]}/{src[1]} sends unsigned messages ({n:,} rejected): "
                "signing is not enabled on the autopilot"
            )
        if self.check.stale[src] > self.check.mismatched[src]:
            return (
                f"{n:,} messages with a bad signature from autopilot {src[0]}/{src[1]}: right "
                "key, old timestamps (replayed, or the autopilot's clock went back)"
            )
        return (
            f"{n:,} messages with a bad signature from autopilot {src[0]}/{src[1]}: the "
            "autopilot signs with another key"
        )
