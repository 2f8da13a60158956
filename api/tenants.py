"""Tenants: who a request's API key says it comes from, and the key settings that define them.

Every key is a tenant. Scenes and long jobs belong to the tenant that made them; another
tenant is answered 404 for them (never 403: a 403 would tell that the name or id exists).

Where the tenants come from (:func:`tenants_from_settings`):

* ``PLANNER_API_KEYS``: a file of ``tenant key`` lines, or an inline list
  ``tenant:key,tenant:key`` (:func:`parse_api_keys`);
* ``PLANNER_API_KEY``: one key, the tenant :data:`DEFAULT_TENANT`;
* neither: no key is asked and every request is the tenant :data:`DEFAULT_TENANT`.

Why the single key and the keyless service share the name ``default``: scenes stored before
tenants existed are migrated to that tenant (:mod:`planner_api.scene_store`), so a service
that keeps its old configuration keeps its scenes; a ``PLANNER_API_KEYS`` deployment names a
tenant ``default`` to inherit them. Setting both variables is refused at start: an operator
moving to ``PLANNER_API_KEYS`` who forgets the old variable would otherwise keep a key alive
that nobody lists.

The key comparison is :func:`secrets.compare_digest` against every configured key, without
stopping at the first match, so the time taken tells nothing about which key (or how much of
one) was right.
"""

from __future__ import annotations

import re
import secrets
from collections.abc import Mapping
from pathlib import Path

__all__ = [
    "DEFAULT_TENANT",
    "TENANT_PATTERN",
    "parse_api_keys",
    "read_key_file",
    "tenant_of",
]

#: The tenant of ``PLANNER_API_KEY`` and of a service without keys (module docstring).
DEFAULT_TENANT = "default"
#: What a tenant's name may be: the rule of a scene's name (it ends up in logs and rows).
TENANT_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$"
_TENANT = re.compile(TENANT_PATTERN)
_NAME_RULE = "1-64 letters, digits, '_', '-' or '.', starting with a letter or a digit"


def _check_entry(
    where: str, tenant: str, key: str, seen: dict[str, str], keys: dict[str, str]
) -> None:
    """Add one (tenant, key) to ``keys`` (key -> tenant) and ``seen`` (tenant -> where);
    ValueError naming ``where`` when the entry breaks a rule. Never puts a key in a message."""
    if not _TENANT.match(tenant):
        raise ValueError(f"{where}: tenant name {tenant!r} must be {_NAME_RULE}")
    if not key:
        raise ValueError(f"{where}: tenant {tenant!r} has an empty key")
    if not (key.isascii() and key.isprintable()) or any(c.isspace() for c in key):
        raise ValueError(
            f"{where}: the key of tenant {tenant!r} must be printable ASCII without spaces "
            "(it travels in an HTTP header)"
        )
    if tenant in seen:
        raise ValueError(f"{where}: tenant {tenant!r} appears twice (first at {seen[tenant]})")
    if key in keys:
        first = seen[keys[key]]
        raise ValueError(f"{where}: the key of tenant {tenant!r} is already the key at {first}")
    seen[tenant] = where
    keys[key] = tenant


def read_key_file(path: Path) -> dict[str, str]:
    """The keys of a tenant file (key -> tenant): one ``tenant key`` line per tenant, the two
    separated by whitespace; lines starting with ``#`` are comments. An empty line, a line
    with one field or more than two, a duplicate tenant or key, a bad tenant name, a file
    that cannot be read or that lists no tenant: ValueError naming the file and the line.
    Why an empty line is refused: a key file is written by tools and people alike, and a
    line broken in two (a key wrapped by an editor) leaves an empty or one-field line; the
    service refuses to guess which tenants were meant."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"PLANNER_API_KEYS file {str(path)!r} cannot be read: {exc}") from exc
    keys: dict[str, str] = {}
    seen: dict[str, str] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        where = f"{path}:{number}"
        if not stripped:
            raise ValueError(
                f"PLANNER_API_KEYS file {where}: an empty line (every line is 'tenant key' or "
                "a '#' comment)"
            )
        if stripped.startswith("#"):
            continue
        fields = stripped.split()
        if len(fields) != 2:
            raise ValueError(
                f"PLANNER_API_KEYS file {where}: a line must be 'tenant key' (two fields "
                f"separated by whitespace), got {len(fields)} field(s)"
            )
        _check_entry(f"PLANNER_API_KEYS file {where}", fields[0], fields[1], seen, keys)
    if not keys:
        raise ValueError(
            f"PLANNER_API_KEYS file {str(path)!r} lists no tenant ('tenant key' lines)"
        )
    return keys


def parse_api_keys(value: str) -> dict[str, str]:
    """The keys a ``PLANNER_API_KEYS`` value defines (key -> tenant).

    A value starting with ``/``, ``./``, ``../`` or ``~`` is a file path
    (:func:`read_key_file`); anything else is an inline list ``tenant:key[,tenant:key...]``
    (the tenant before the first ``:``, the key after it; a key holds no ``,``). ValueError
    naming the entry (its position) or the file and line when the value breaks a rule."""
    text = value.strip()
    if text.startswith(("/", "./", "../", "~")):
        return read_key_file(Path(text).expanduser())
    keys: dict[str, str] = {}
    seen: dict[str, str] = {}
    for number, item in enumerate(text.split(","), start=1):
        entry = item.strip()
        where = f"PLANNER_API_KEYS entry {number}"
        tenant, colon, key = entry.partition(":")
        if not colon:
            raise ValueError(f"{where}: expected 'tenant:key' (a file path starts with /, ./ or ~)")
        _check_entry(where, tenant.strip(), key.strip(), seen, keys)
    return keys


def tenant_of(headers: Mapping[str, str], keys: Mapping[str, str]) -> str | None:
    """The tenant whose key a request presents in ``X-API-Key``, else in ``Authorization:
    Bearer <key>``; None when it presents none of ``keys`` (key -> tenant). Every key is
    compared, in constant time (module docstring)."""
    given = headers.get("x-api-key")
    if given is None:
        scheme, _, token = headers.get("authorization", "").partition(" ")
        given = token.strip() if scheme.lower() == "bearer" else None
    if given is None:
        return None
    presented = given.encode()
    found: str | None = None
    for key, tenant in keys.items():
        if secrets.compare_digest(presented, key.encode()) and found is None:
            found = tenant
    return found
