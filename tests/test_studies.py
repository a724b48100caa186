"""The package sunlab.studies: its studies load on first use, and nothing else is found there."""

import importlib

import pytest

import sunlab.studies as studies


def test_each_listed_study_is_its_module():
    assert studies.__all__
    for name in studies.__all__:
        assert getattr(studies, name) is importlib.import_module(f"sunlab.studies.{name}")


def test_an_unknown_study_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no_such_study"):
        studies.no_such_study  # noqa: B018
