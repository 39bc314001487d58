"""The API contract: the pydantic request and response models that the server and the client both use.

The ``...Create`` (request) and ``...Public`` (response) models live in one module per group of routes (``base``,
``resources``, ``reports``, ``jobs``, ``visibility``, ``gaussian``, ``tradeoffs``, ``scenes``);
``relight.contract.models`` re-exports every one of them, ``relight.contract.brdfs`` holds the BRDF specs (a
discriminated union on ``kind``). The server validates requests and
serialises answers with them; the SDK (``relight.client``) parses answers with them, so both sides agree on every
field. The scene schema's limits are the core's (``relight.planning.scene``): a scene the CLI accepts, the API accepts.

Layering (``make lint`` runs import-linter): the contract imports pydantic and core constants only; the server and
the client import it, and neither imports the other.
"""
