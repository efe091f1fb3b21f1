// star_id (to be written)
