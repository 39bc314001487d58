"""The API contract: the pydantic request and response models that the server and the client both use.

``relight.contract.models`` holds the ``...Create`` (request) and ``...Public`` (response) models,
``relight.contract.brdfs`` the BRDF specs (a discriminated union on ``kind``). The server validates requests and
serialises answers with them; the SDK (``relight.client``) parses answers with them, so both sides agree on every
field. The scene schema's limits are the core's (``relight.planning.scene``): a scene the CLI accepts, the API accepts.

Layering (``make lint`` runs import-linter): the contract imports pydantic and core constants only; the server and
the client import it, and neither imports the other.
"""
