"""Model classes beyond the joint springs: link compliance, an axis-2 compensator, lost
motion; their identification and the choice between them (issue 32)."""
