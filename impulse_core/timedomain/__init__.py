"""Time-domain models of a landing: sequential rigid impacts and compliant contacts."""
