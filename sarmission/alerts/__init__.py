"""Durable alert store, operator feed server and Cursor-on-Target export."""
