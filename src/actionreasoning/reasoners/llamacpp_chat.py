"""A GGUF model in process through llama-cpp-python (the optional ``local`` extra).

Output is constrained by a grammar built from the agent's JSON schema, so the model can
only write JSON of the schema's shape; validation still checks the values.

Of the sampling settings, temperature, the token cap and the seed go with every request (the
seed per request, so an answer depends on its request alone), and top-p when set (else
llama-cpp-python's 0.95, which greedy decoding at temperature 0 never uses). llama.cpp has no
reasoning effort: :func:`~actionreasoning.reasoners.factory.prepare` refuses one.
"""

from __future__ import annotations

import atexit
import os
import time
from functools import cache
from pathlib import Path
from typing import Any

from actionreasoning.errors import ConfigError, LLMError
from actionreasoning.reasoners.chat import ChatReply, ChatRequest
from actionreasoning.reasoners.sampling import Sampling
from actionreasoning.records import FailureCode, LLMUsage

CONTEXT_TOKENS = 8192


@cache
def _load(path: str) -> Any:
    """The model, loaded once per process."""
    from llama_cpp import Llama  # the local extra; registry.py names it when it is missing

    if not Path(path).is_file():
        raise ConfigError(f"--llm llamacpp:{path}: no such model file")
    try:
        model = Llama(
            model_path=path,
            n_ctx=CONTEXT_TOKENS,
            n_threads=os.cpu_count() or 1,
            verbose=False,
        )
    except ValueError as error:
        raise ConfigError(f"--llm llamacpp:{path}: cannot load the model ({error})") from None
    # Freed before the interpreter tears its modules down: a model the cache still holds
    # then would be freed by Llama.__del__ with llama_cpp's functions already gone
    # ("Exception ignored ... 'NoneType' object is not callable"). Closing twice is harmless.
    atexit.register(model.close)
    architecture = model.metadata.get("general.architecture", "")
    if "tokenizer.chat_template" not in model.metadata and architecture.startswith("gemma"):
        model.chat_format = "gemma"  # a Gemma GGUF without its template: use Gemma's turns
    return model


class LlamaCppChat:
    """Chat completions from a local GGUF model with grammar-constrained JSON."""

    def __init__(self, path: str, sampling: Sampling = Sampling()) -> None:
        self.label = f"llamacpp:{path}"
        self.model = _load(path)
        self.sampling = sampling

    def complete(self, request: ChatRequest) -> ChatReply:
        """One completion constrained to the request's JSON schema."""
        started = time.perf_counter()
        sampling = self.sampling
        top_p = {} if sampling.top_p is None else {"top_p": sampling.top_p}
        try:
            result = self.model.create_chat_completion(
                messages=list(request.messages),
                response_format={"type": "json_object", "schema": request.schema},
                temperature=sampling.temperature,
                max_tokens=sampling.max_tokens,
                seed=sampling.seed,
                **top_p,
            )
        except ValueError as error:  # e.g. a prompt longer than the context
            raise LLMError(
                FailureCode.LLM_BAD_REQUEST, f"llama.cpp refused the request: {error}"
            ) from None
        usage = result.get("usage") or {}
        return ChatReply(
            model=str(result.get("model", self.label)),
            content=result["choices"][0]["message"].get("content") or "",
            usage=LLMUsage(
                calls=1,
                prompt_tokens=usage.get("prompt_tokens", 0),
                completion_tokens=usage.get("completion_tokens", 0),
                latency_s=time.perf_counter() - started,
            ),
        )
